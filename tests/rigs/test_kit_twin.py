"""The kit's two-heater twin (``sim:kit``): both heaters, both sensors, the kit's physics."""

from __future__ import annotations

import pytest

from thermolab.errors import InvalidParameterError, RigFaultError, RigStateError
from thermolab.kit_physics import KitPhysics
from thermolab.rigs import KitTwinRig, RigSpec, RigState, VirtualClock, open_rig


def test_it_follows_the_published_energy_balance_on_both_channels() -> None:
    clock = VirtualClock()
    rig = KitTwinRig(clock=clock, realism=False)
    rig.power_on()
    rig.apply(40.0)
    rig.set_channel("q2", 70.0)
    clock.advance(900.0)
    reading = rig.read()
    kit = KitPhysics()
    kit.advance(900.0, q1=40.0, q2=70.0, p1=200.0, p2=100.0)
    assert kit.temperatures is not None
    assert reading.value == pytest.approx(kit.temperatures[2])
    assert reading.further["t2"] == pytest.approx(kit.temperatures[3])
    assert reading.t == 900.0


def test_readings_have_the_kits_quantisation() -> None:
    rig = KitTwinRig(clock=VirtualClock(), seed=3)
    reading = rig.read()
    for value in (reading.value, reading.further["t2"]):
        assert value / 0.3223 == pytest.approx(round(value / 0.3223), abs=1e-3)


def test_heater_2_rests_at_0_in_every_safe_state() -> None:
    clock = VirtualClock()
    rig = KitTwinRig(clock=clock, realism=False, output_limit=30.0)
    with pytest.raises(RigStateError):
        rig.set_channel("q2", 10.0)  # idle: refused
    assert rig.set_channel("q2", 0.0) == 0.0  # the default is where it already is
    rig.power_on()
    rig.set_channel("q2", 50.0)
    rig.power_off()
    assert rig.level("q2") == 0.0
    rig.power_on()
    rig.set_channel("q2", 100.0)
    clock.advance(1200.0)
    with pytest.raises(RigFaultError, match="output t2"):
        rig.read()  # sensor 2 over its limit: the over-temperature check watches it
    assert rig.state is RigState.FAULTED
    assert (rig.level("q2"), rig.applied_input) == (0.0, 0.0)
    rig.close()
    assert rig.level("q2") == 0.0


def test_the_spec_declares_it_and_opens_it() -> None:
    spec = RigSpec.parse("sim:kit")
    assert spec.simulated
    assert spec.rest_state() == {"u": 0.0, "q2": 0.0}
    assert spec.fan is None
    info = spec.describe()
    assert [c.name for c in info.further_outputs] == ["t2"]
    with open_rig("sim:kit", clock=VirtualClock(), seed=1) as rig:
        assert rig.describe() == info
    with pytest.raises(InvalidParameterError, match="realism and output_limit"):
        spec.describe(dead_time=5.0)
    # The first-order twin of the kit keeps its figures (one heater, no further channels).
    assert RigSpec.parse("sim:tclab").describe().further_outputs == ()
    assert list(RigSpec.parse("sim:tclab").actuators) == ["fan"]
