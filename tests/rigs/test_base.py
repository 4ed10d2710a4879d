"""The shared safety behaviour of BaseRig: state machine, validation, safe state."""

from __future__ import annotations

import math

import pytest

from thermolab.errors import InvalidParameterError, RigFaultError, RigStateError
from thermolab.rigs.base import BaseRig, Reading, Rig, RigInfo, RigState
from thermolab.rigs.clock import VirtualClock


class _Recorder(BaseRig):
    """A rig that records what the base class asks of it."""

    def __init__(self, *, limit: float | None = 5.0) -> None:
        super().__init__(
            RigInfo("recorder", "test", -2.0, 8.0, "V", "V", 1.0, limit), VirtualClock()
        )
        self.actuator = 1.0
        self.output = 0.0
        self.calls: list[str] = []
        self.fail_apply = False
        self.fail_read = False
        self.fail_safe = False

    def _apply_input(self, u: float) -> float:
        self.calls.append(f"apply {u}")
        if self.fail_apply:
            raise RigFaultError("device refused")
        self.actuator = u
        return u

    def _read_output(self) -> Reading:
        self.calls.append("read")
        if self.fail_read:
            raise RigFaultError("sensor gone")
        return Reading(self.output, self.clock.now())

    def _make_safe(self) -> None:
        self.calls.append("safe")
        if self.fail_safe:
            return  # a best-effort hook that could not reach the device
        self.actuator = self.describe().safe_input

    def _release(self) -> None:
        self.calls.append("release")


def test_a_base_rig_satisfies_the_protocol() -> None:
    assert isinstance(_Recorder(), Rig)


def test_lifecycle_idle_powered_idle_closed() -> None:
    rig = _Recorder()
    assert rig.state is RigState.IDLE
    assert not rig.powered
    rig.power_on()
    rig.power_on()  # idempotent
    assert rig.powered
    assert rig.apply(7.5) == 7.5
    rig.power_off()
    assert rig.state is RigState.IDLE
    assert rig.actuator == 1.0
    rig.close()
    rig.close()  # idempotent
    assert rig.state is RigState.CLOSED
    assert rig.calls.count("release") == 1


def test_apply_is_refused_unless_powered() -> None:
    rig = _Recorder()
    with pytest.raises(RigStateError, match="power_on"):
        rig.apply(2.0)
    assert "apply 2.0" not in rig.calls


@pytest.mark.parametrize("bad", [8.01, -2.5, math.nan, math.inf, "warm"])
def test_apply_refuses_values_outside_the_range_and_names_it(bad: object) -> None:
    rig = _Recorder()
    rig.power_on()
    with pytest.raises(InvalidParameterError, match=r"\[-2, 8\] V"):
        rig.apply(bad)  # type: ignore[arg-type]
    assert rig.actuator == 1.0


def test_range_bounds_are_inclusive() -> None:
    rig = _Recorder()
    rig.power_on()
    assert rig.apply(-2.0) == -2.0
    assert rig.apply(8.0) == 8.0


def test_a_device_fault_latches_makes_safe_and_blocks_apply() -> None:
    rig = _Recorder()
    rig.power_on()
    rig.apply(6.0)
    rig.fail_read = True
    with pytest.raises(RigFaultError, match="sensor gone"):
        rig.read()
    assert rig.state is RigState.FAULTED
    assert rig.fault() == "sensor gone"
    assert rig.actuator == 1.0
    with pytest.raises(RigStateError, match="faulted"):
        rig.apply(2.0)
    with pytest.raises(RigStateError, match="clear_fault"):
        rig.power_on()
    rig.power_off()  # allowed, stays faulted
    assert rig.state is RigState.FAULTED


def test_clear_fault_refuses_while_the_cause_persists() -> None:
    rig = _Recorder()
    rig.power_on()
    rig.fail_apply = True
    with pytest.raises(RigFaultError):
        rig.apply(3.0)
    rig.fail_read = True
    with pytest.raises(RigFaultError):
        rig.clear_fault()
    assert rig.state is RigState.FAULTED
    rig.fail_read = False
    rig.clear_fault()
    assert rig.state is RigState.IDLE
    assert rig.fault() is None
    rig.power_on()


def test_an_output_above_the_limit_faults_and_makes_safe() -> None:
    rig = _Recorder(limit=5.0)
    rig.power_on()
    rig.apply(8.0)
    rig.output = 5.5
    with pytest.raises(RigFaultError, match=r"exceeds the limit of 5 V"):
        rig.read()
    assert rig.actuator == 1.0
    assert rig.state is RigState.FAULTED
    # Reading is still allowed while faulted (watch it cool down) ...
    assert rig.read().value == 5.5
    # ... and the fault clears only below the limit.
    with pytest.raises(RigFaultError):
        rig.clear_fault()
    rig.output = 4.0
    rig.clear_fault()
    assert rig.state is RigState.IDLE


def test_a_nan_reading_counts_as_over_the_limit() -> None:
    rig = _Recorder(limit=5.0)
    rig.output = math.nan
    with pytest.raises(RigFaultError):
        rig.read()


def test_closed_rig_refuses_everything_but_close_and_power_off() -> None:
    rig = _Recorder()
    rig.close()
    for action in (rig.read, rig.power_on, rig.clear_fault, lambda: rig.apply(1.0)):
        with pytest.raises(RigStateError, match="closed"):
            action()
    rig.power_off()
    rig.close()
    assert rig.describe().name == "recorder"


def test_leaving_a_with_block_by_an_exception_closes_and_makes_safe() -> None:
    rig = _Recorder()

    def run() -> None:
        with rig:
            rig.power_on()
            rig.apply(7.0)
            raise ZeroDivisionError

    with pytest.raises(ZeroDivisionError):
        run()
    assert rig.state is RigState.CLOSED
    assert rig.actuator == 1.0
    assert rig.calls[-2:] == ["safe", "release"]


def test_a_safe_input_outside_the_range_is_refused() -> None:
    class Bad(_Recorder):
        def __init__(self) -> None:
            BaseRig.__init__(
                self, RigInfo("bad", "test", 0.0, 1.0, "V", "V", 2.0, None), VirtualClock()
            )

    with pytest.raises(InvalidParameterError, match="safe input"):
        Bad()


def test_rig_info_to_dict_round_trips() -> None:
    info = RigInfo("x", "twin", -1.0, 1.0, "V", "V", 0.0, 2.0, "demo")
    assert RigInfo(**info.to_dict()) == info
    assert info.input_range == (-1.0, 1.0)
