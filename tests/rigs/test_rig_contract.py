"""The one rig contract, run against every implementation.

Subjects: the twin in each preset, the TCLab driver against the firmware
emulator on a pseudo-terminal, and (``hardware`` marker) a real TCLab kit on
the port named by ``THERMOLAB_TCLAB_PORT``.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from thermolab.errors import InvalidParameterError, RigFaultError, RigStateError
from thermolab.rigs import Rig, RigState, TCLabRig, TwinRig, open_rig
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab_emulator import TCLabEmulator


@dataclass
class Subject:
    """A rig under test and the means to drive and observe it from outside."""

    rig: Rig
    advance: Callable[[float], None]  # let this many seconds pass on the rig's clock
    actuator: Callable[[], float | None]  # what the actuator holds, seen from outside
    break_it: Callable[[], None]  # make the next read fail
    heat_seconds: float  # long enough at full input to see the output rise ...
    min_rise: float  # ... by at least this much (output units), far above the noise


def _twin_subject(preset: str) -> Iterator[Subject]:
    clock = VirtualClock()
    rig = TwinRig(preset, clock=clock, seed=42)
    yield Subject(
        rig=rig,
        advance=clock.advance,
        actuator=lambda: rig.applied_input,
        break_it=lambda: rig.inject_fault("broken on purpose"),
        heat_seconds=300.0,
        min_rise=0.5 if preset.startswith("paper") else 10.0,
    )
    rig.close()


def _emulated_tclab_subject() -> Iterator[Subject]:
    clock = VirtualClock()
    with TCLabEmulator(clock=clock, seed=42) as emulator:
        rig = open_rig(
            f"tclab:{emulator.port}", clock=clock, reset_wait=0.0, timeout=2.0, watchdog=None
        )

        def break_it() -> None:
            emulator.silent = True

        yield Subject(
            rig=rig,
            advance=clock.advance,
            actuator=lambda: emulator.heater(1),
            break_it=break_it,
            heat_seconds=300.0,
            min_rise=10.0,
        )
        rig.close()


def _hardware_subject() -> Iterator[Subject]:
    port = os.environ.get("THERMOLAB_TCLAB_PORT")
    if not port:
        pytest.skip("no TCLab kit: set THERMOLAB_TCLAB_PORT to its serial port")
    rig = TCLabRig(port, timeout=2.0)

    def actuator() -> float | None:
        return rig._number("R1") if rig.state is not RigState.CLOSED else None

    def break_it() -> None:
        pytest.skip("a real kit cannot be broken on purpose")

    yield Subject(
        rig=rig,
        advance=time.sleep,
        actuator=actuator,
        break_it=break_it,
        heat_seconds=120.0,
        min_rise=2.0,
    )
    rig.close()


@pytest.fixture(
    params=[
        "twin:paper",
        "twin:paper-practical",
        "twin:tclab",
        "tclab:emulator",
        pytest.param("tclab:hardware", marks=pytest.mark.hardware),
    ]
)
def subject(request: pytest.FixtureRequest) -> Iterator[Subject]:
    kind, _, which = str(request.param).partition(":")
    if kind == "twin":
        yield from _twin_subject(which)
    elif which == "emulator":
        yield from _emulated_tclab_subject()
    else:
        yield from _hardware_subject()


def _safe(subject: Subject) -> float:
    return subject.rig.describe().safe_input


def test_it_is_a_rig(subject: Subject) -> None:
    assert isinstance(subject.rig, Rig)


def test_every_further_input_rests_at_its_default_after_power_off_and_close(
    subject: Subject,
) -> None:
    # Issue #23 for every declared further input (a twin's fan, a kit's heater 2).
    rig = subject.rig
    inputs = rig.describe().further_inputs
    assert inputs, "every rig here declares a further input"
    rig.power_on()
    for channel in inputs:
        assert rig.set_channel(channel.name, channel.maximum) == channel.maximum
        assert rig.level(channel.name) == channel.maximum
    rig.power_off()
    assert {c.name: rig.level(c.name) for c in inputs} == {c.name: c.default for c in inputs}
    rig.power_on()
    for channel in inputs:
        rig.set_channel(channel.name, channel.maximum)
    rig.close()
    assert {c.name: rig.level(c.name) for c in inputs} == {c.name: c.default for c in inputs}


def test_describe_is_consistent(subject: Subject) -> None:
    info = subject.rig.describe()
    assert info.input_min < info.input_max
    assert info.input_min <= info.safe_input <= info.input_max
    assert info.input_unit
    assert info.output_unit
    assert info.kind in ("twin", "tclab")
    assert info.name
    assert info.output_limit is None or math.isfinite(info.output_limit)


def test_it_starts_idle_and_safe(subject: Subject) -> None:
    rig = subject.rig
    assert rig.state is RigState.IDLE
    assert not rig.powered
    assert rig.fault() is None
    assert subject.actuator() == _safe(subject)


def test_apply_needs_power(subject: Subject) -> None:
    with pytest.raises(RigStateError, match="power_on"):
        subject.rig.apply(subject.rig.describe().input_max)
    assert subject.actuator() == _safe(subject)


def test_apply_returns_what_was_applied(subject: Subject) -> None:
    rig = subject.rig
    info = rig.describe()
    rig.power_on()
    assert rig.powered
    middle = (info.input_min + info.input_max) / 2 + 0.1234
    applied = rig.apply(middle)
    assert applied == pytest.approx(middle, abs=1e-3 * (info.input_max - info.input_min))
    assert subject.actuator() == pytest.approx(applied, abs=1e-9)
    assert rig.apply(info.input_max) == pytest.approx(info.input_max)
    assert rig.apply(info.input_min) == pytest.approx(info.input_min)


@pytest.mark.parametrize("where", ["below", "above", "nan", "inf"])
def test_out_of_range_input_is_refused_with_the_range(subject: Subject, where: str) -> None:
    rig = subject.rig
    info = rig.describe()
    rig.power_on()
    rig.apply(info.safe_input)
    span = info.input_max - info.input_min
    bad = {
        "below": info.input_min - 0.01 * span,
        "above": info.input_max + 0.01 * span,
        "nan": math.nan,
        "inf": math.inf,
    }[where]
    with pytest.raises(InvalidParameterError, match=rf"\[{info.input_min:g}, {info.input_max:g}\]"):
        rig.apply(bad)
    assert subject.actuator() == _safe(subject)
    assert rig.state is RigState.POWERED


def test_read_gives_a_finite_value_and_its_time(subject: Subject) -> None:
    rig = subject.rig
    before = rig.clock.now()
    reading = rig.read()
    after = rig.clock.now()
    assert math.isfinite(reading.value)
    assert before <= reading.t <= after


def test_full_input_raises_the_output(subject: Subject) -> None:
    rig = subject.rig
    start = rig.read().value
    rig.power_on()
    rig.apply(rig.describe().input_max)
    subject.advance(subject.heat_seconds)
    assert rig.read().value > start + subject.min_rise


def test_power_off_returns_to_safe(subject: Subject) -> None:
    rig = subject.rig
    rig.power_on()
    rig.apply(rig.describe().input_max)
    rig.power_off()
    rig.power_off()  # idempotent
    assert rig.state is RigState.IDLE
    assert subject.actuator() == _safe(subject)
    with pytest.raises(RigStateError):
        rig.apply(rig.describe().input_max)
    rig.read()  # reading is still allowed


def test_close_is_safe_idempotent_and_final(subject: Subject) -> None:
    rig = subject.rig
    rig.power_on()
    rig.apply(rig.describe().input_max)
    rig.close()
    rig.close()
    rig.power_off()
    assert rig.state is RigState.CLOSED
    assert subject.actuator() in (_safe(subject), None)
    with pytest.raises(RigStateError, match="closed"):
        rig.read()
    with pytest.raises(RigStateError, match="closed"):
        rig.apply(_safe(subject))
    with pytest.raises(RigStateError, match="closed"):
        rig.power_on()


def test_an_exception_in_a_with_block_leaves_it_safe(subject: Subject) -> None:
    rig = subject.rig

    def crash() -> None:
        with rig:
            rig.power_on()
            rig.apply(rig.describe().input_max)
            raise KeyError("crash")

    with pytest.raises(KeyError):
        crash()
    assert rig.state is RigState.CLOSED
    assert subject.actuator() in (_safe(subject), None)


def test_a_fault_latches_is_reported_and_leaves_it_safe(subject: Subject) -> None:
    rig = subject.rig
    rig.power_on()
    rig.apply(rig.describe().input_max)
    subject.break_it()
    with pytest.raises(RigFaultError):
        rig.read()
    assert rig.state is RigState.FAULTED
    assert isinstance(rig.fault(), str)
    assert subject.actuator() == _safe(subject)
    with pytest.raises(RigStateError, match="faulted"):
        rig.apply(rig.describe().input_max)
    with pytest.raises(RigStateError, match="clear_fault"):
        rig.power_on()
    rig.close()
    assert rig.state is RigState.CLOSED
