"""A closed loop on the kit's heater 2 from its sensor 2, heater 1 a disturbance (issue #22)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from thermolab.control import PIDGains
from thermolab.errors import ChannelInLoopError, InvalidParameterError, LoopPairNotOnRigError
from thermolab.rigs import KitTwinRig, VirtualClock
from thermolab.rigs.twin import TwinRig
from thermolab.runner import ControlLoop, Experiment
from thermolab.runner.control_request import ControlRequest, build_control_loop

from .conftest import HookedKit

GAINS = PIDGains(5.0, 150.0)  # a PI for either heater of the kit's twin
SETPOINT = 40.0
DT, SAMPLES = 2.0, 700


@pytest.fixture
def kit() -> Iterator[HookedKit]:
    with HookedKit(clock=VirtualClock(), realism=False) as rig:
        yield rig


def q2_loop() -> ControlLoop:
    return ControlLoop(GAINS, SETPOINT, heater="q2", sensor="t2")


def test_the_pid_drives_heater_2_from_sensor_2_and_leaves_heater_1_alone(kit: HookedKit) -> None:
    exp = Experiment(kit, DT, SAMPLES, controller=q2_loop())
    result = exp.run()
    assert result.ok
    t2, q2 = result.extra["t2"], result.extra["q2"]
    assert abs(t2[-1] - SETPOINT) < 0.2  # sensor 2 tracks the set point...
    np.testing.assert_allclose(result.extra["r"], SETPOINT)
    np.testing.assert_allclose(result.extra["e"], SETPOINT - t2, atol=1e-12)
    np.testing.assert_allclose(result.extra["u_pid"], q2)  # ...with heater 2, the PID's
    assert q2.max() > 30.0
    assert set(result.u) == {0.0}  # heater 1 stays at its default: nobody stepped it
    assert result.y[-1] < t2[-1] - 5.0  # sensor 1 only warms through the kit
    assert result.control is not None
    assert (result.control["heater"], result.control["sensor"]) == ("q2", "t2")
    units = {c.name: c.unit for c in result.channels}
    assert (units["u_pid"], units["r"]) == ("%", "degC")
    # The run's end put every actuator back at its declared default.
    assert (kit.applied_input, kit.level("q2")) == (0.0, 0.0)


def test_sensor_2_tracks_better_than_the_open_loop_would(kit: HookedKit) -> None:
    closed = Experiment(kit, DT, SAMPLES, controller=q2_loop()).run()
    with KitTwinRig(clock=VirtualClock(), realism=False) as other:
        opened = Experiment(other, DT, SAMPLES).run()  # heater 2 held at its default
    error_closed = np.abs(closed.extra["t2"][-100:] - SETPOINT).mean()
    error_open = np.abs(opened.extra["t2"][-100:] - SETPOINT).mean()
    assert error_closed < 0.2 < 10.0 < error_open


def test_a_step_of_heater_1_is_a_disturbance_the_loop_rejects(kit: HookedKit) -> None:
    exp = Experiment(kit, DT, 1000, controller=q2_loop())
    kit.hooks[500] = lambda: exp.set_input(80.0)
    result = exp.run()
    u, q2, t2 = result.u, result.extra["q2"], result.extra["t2"]
    step = int(np.flatnonzero(u)[0])
    assert step in (500, 501)  # recorded from the sample it was applied at
    assert set(u[step:]) == {80.0}
    assert set(result.extra["auto"]) == {1.0}  # the loop stays in AUTO
    assert t2[step : step + 150].max() > SETPOINT + 0.3  # heater 1 warms sensor 2...
    assert abs(t2[-1] - SETPOINT) < 0.3  # ...and the PID brings it back
    assert q2[-1] < q2[step - 1] - 5.0  # with less of heater 2


def test_heater_2_is_the_loops_and_manual_holds_it(kit: HookedKit) -> None:
    exp = Experiment(kit, DT, 400, controller=q2_loop())

    def refuse_then_hold() -> None:
        with pytest.raises(ChannelInLoopError, match="q2 is driven by this run's closed loop"):
            exp.set_further("q2", 10.0)
        with pytest.raises(InvalidParameterError, match="q2 of 'twin:kit' takes 0-100"):
            exp.set_manual(140.0)
        exp.set_manual(25.0)  # the loop's heater, held by hand through the loop

    kit.hooks[200] = refuse_then_hold
    result = exp.run()
    q2, auto = result.extra["q2"], result.extra["auto"]
    assert q2[199] != 25.0
    assert set(q2[201:]) == {25.0}
    assert set(auto[201:]) == {0.0}
    assert set(result.u) == {0.0}  # manual on heater 2 leaves heater 1 alone


def test_a_pair_the_rig_does_not_have_is_refused() -> None:
    with TwinRig("paper", clock=VirtualClock()) as box:
        request = ControlRequest(1.0, 5.0, 150.0, heater="q2", sensor="t2")
        with pytest.raises(LoopPairNotOnRigError, match="its pairs: u/y"):
            build_control_loop(request, 1.0, [0.0], box.describe())
    with KitTwinRig(clock=VirtualClock()) as kit:
        crossed = ControlRequest(SETPOINT, 5.0, 150.0, heater="q2", sensor="y")
        with pytest.raises(LoopPairNotOnRigError, match=r"q2/y .*its pairs: u/y, q2/t2"):
            build_control_loop(crossed, 1.0, [0.0], kit.describe())
        with pytest.raises(LoopPairNotOnRigError):
            Experiment(kit, 1.0, 5, controller=ControlLoop(GAINS, 30.0, heater="fan"))


def test_the_default_pair_is_the_runs_own() -> None:
    request = ControlRequest(30.0, 5.0, 150.0)
    assert (request.heater, request.sensor) == ("u", "y")
    assert request.settings()["heater"] == "u"  # the record says which pair
    with KitTwinRig(clock=VirtualClock(), realism=False) as kit:
        exp = Experiment(kit, DT, 300, controller=ControlLoop(GAINS, 35.0))
        kit_result = exp.run()
    assert abs(kit_result.y[-1] - 35.0) < 0.5
    assert set(kit_result.extra["q2"]) == {0.0}
