"""The shared behaviour of every rig: :class:`BaseRig`.

:class:`BaseRig` implements the parts of the :class:`~thermolab.rigs.contract.Rig`
contract that must not be got wrong twice: the lifecycle state machine, input
validation, the output limit, and the safe state on every way out. A rig
writes four hooks and never deals with states itself.

The contract's types (:class:`Rig`, :class:`RigInfo`, :class:`Reading`,
:class:`RigState`) are declared in :mod:`thermolab.rigs.contract`; they are
re-exported here, where rigs have always imported them from.
"""

from __future__ import annotations

import abc
import math
import threading
from types import TracebackType
from typing import Self

from thermolab.errors import (
    InvalidParameterError,
    RigError,
    RigFaultError,
    RigStateError,
    RigTimeoutError,
)
from thermolab.rigs.clock import Clock
from thermolab.rigs.contract import Reading, Rig, RigInfo, RigState

__all__ = [
    "BaseRig",
    "Reading",
    "Rig",
    "RigError",
    "RigFaultError",
    "RigInfo",
    "RigState",
    "RigStateError",
    "RigTimeoutError",
]


# Which transitions the state machine allows; anything else is a programming error.
_TRANSITIONS: dict[RigState, frozenset[RigState]] = {
    RigState.IDLE: frozenset({RigState.POWERED, RigState.FAULTED, RigState.CLOSED}),
    RigState.POWERED: frozenset({RigState.IDLE, RigState.FAULTED, RigState.CLOSED}),
    RigState.FAULTED: frozenset({RigState.IDLE, RigState.CLOSED}),
    RigState.CLOSED: frozenset(),
}


class BaseRig(abc.ABC):
    """Shared behaviour of every rig: state machine, validation, safe state.

    Subclasses implement four hooks and never deal with states themselves
    (a hook that needs the instant it acts at calls :meth:`_instant`):

    * ``_apply_input(u) -> float``: drive the actuator with a validated,
      in-range ``u``; return the value actually applied.
    * ``_read_output() -> Reading``: take one reading.
    * ``_make_safe()``: put the actuator at the safe value. Called on
      power-off, fault and close; must be best-effort and must not raise.
    * ``_release()``: free resources (port, threads). Called once, after
      ``_make_safe``; must not raise.

    A hook that raises :class:`~thermolab.errors.RigFaultError` latches the
    fault: the state becomes FAULTED, the actuator is made safe, and the error
    propagates. A reading above ``output_limit`` does the same.

    Parameters
    ----------
    info : RigInfo
        The description returned by :meth:`describe`.
    clock : Clock
        The clock of the rig.

    Notes
    -----
    All public methods hold one re-entrant lock, so a watchdog thread, a
    runner and a server may share a rig.
    """

    def __init__(self, info: RigInfo, clock: Clock) -> None:
        if not (info.input_min <= info.safe_input <= info.input_max):
            raise InvalidParameterError(
                f"safe input {info.safe_input} is outside the input range "
                f"[{info.input_min}, {info.input_max}]"
            )
        self._info = info
        self._clock = clock
        self._state = RigState.IDLE
        self._fault: str | None = None
        self._lock = threading.RLock()
        self._at: float | None = None  # the sample instant of the call in progress

    # -- hooks -------------------------------------------------------------

    @abc.abstractmethod
    def _apply_input(self, u: float) -> float:
        """Drive the actuator with ``u`` (validated); return the value applied."""

    @abc.abstractmethod
    def _read_output(self) -> Reading:
        """Take one reading from the sensor."""

    @abc.abstractmethod
    def _make_safe(self) -> None:
        """Best-effort: put the actuator at its safe value. Must not raise."""

    @abc.abstractmethod
    def _release(self) -> None:
        """Free resources. Must not raise."""

    def _set_further_input(self, name: str, value: float) -> float:
        """Drive the further input ``name`` (declared, validated); return the level set.

        Only a rig that declares further inputs is ever asked; its
        ``_make_safe`` puts each back at its default.
        """
        raise NotImplementedError(f"{type(self).__name__} declares {name!r} but cannot set it")

    def _further_level(self, name: str) -> float:
        """The further input ``name``'s level now (declared)."""
        raise NotImplementedError(f"{type(self).__name__} declares {name!r} but cannot read it")

    def _check_fault_cleared(self) -> None:
        """Raise :class:`RigFaultError` if the cause of the fault persists.

        The default re-reads the output and checks it against the limit.
        """
        reading = self._read_output()
        self._check_limit(reading)

    # -- properties ------------------------------------------------------------

    @property
    def state(self) -> RigState:
        """The lifecycle state."""
        return self._state

    @property
    def powered(self) -> bool:
        """``True`` in state POWERED."""
        return self._state is RigState.POWERED

    @property
    def clock(self) -> Clock:
        """The clock of the rig."""
        return self._clock

    # -- public interface --------------------------------------------------------

    def describe(self) -> RigInfo:
        """Return the rig's :class:`RigInfo`."""
        return self._info

    def fault(self) -> str | None:
        """Return the reason of the latched fault, or ``None``."""
        return self._fault

    def power_on(self) -> None:
        """Enter POWERED; ``apply`` then drives the actuator.

        Raises
        ------
        RigStateError
            If the rig is faulted or closed.
        """
        with self._lock:
            if self._state is RigState.POWERED:
                return
            if self._state is RigState.FAULTED:
                raise RigStateError(
                    f"cannot power on {self._info.name!r}: it is faulted ({self._fault}); "
                    "call clear_fault() once the cause is gone"
                )
            self._transition(RigState.POWERED)

    def power_off(self) -> None:
        """Put the actuator at its safe value and leave POWERED (idempotent, never raises)."""
        with self._lock:
            self._make_safe()
            if self._state is RigState.POWERED:
                self._transition(RigState.IDLE)

    def apply(self, u: float, *, at: float | None = None) -> float:
        """Drive the actuator.

        Parameters
        ----------
        u : float
            Input in the rig's input unit, within ``describe().input_range``.
        at : float, optional
            The scheduled clock instant of the sample this input belongs to
            (the experiment runner passes ``t0 + k·dt``). A simulated rig
            applies the input exactly there, whatever the wall clock did in
            between, so its record is exact at any speed-up; hardware acts
            when called and ignores it. ``None``: now.

        Returns
        -------
        float
            The value actually applied (after the rig's own clipping or
            rounding, e.g. actuator saturation or the firmware's 3 decimals).

        Raises
        ------
        RigStateError
            If the rig is not POWERED (idle, faulted or closed).
        InvalidParameterError
            If ``u`` is not finite or outside the input range.
        RigFaultError
            If the device faults while applying (the fault is latched and the
            actuator made safe).
        """
        with self._lock:
            if self._state is not RigState.POWERED:
                raise RigStateError(self._refusal("apply an input"))
            info = self._info
            try:
                value = float(u)
            except (TypeError, ValueError):
                raise InvalidParameterError(
                    f"input must be a number in [{info.input_min:g}, {info.input_max:g}] "
                    f"{info.input_unit}, got {u!r}"
                ) from None
            if not (math.isfinite(value) and info.input_min <= value <= info.input_max):
                raise InvalidParameterError(
                    f"input {value!r} {info.input_unit} is outside the range of "
                    f"{info.name!r}: [{info.input_min:g}, {info.input_max:g}] {info.input_unit}"
                )
            self._at = _check_instant(at)
            try:
                return self._apply_input(value)
            except RigFaultError as exc:
                self._latch(str(exc))
                raise
            finally:
                self._at = None

    def read(self, *, at: float | None = None) -> Reading:
        """Take one reading.

        Allowed in IDLE, POWERED and FAULTED (watching a rig cool down after an
        over-temperature fault is useful).

        Parameters
        ----------
        at : float, optional
            The scheduled clock instant of the sample (see :meth:`apply`): a
            simulated rig samples its state there and stamps the reading with
            it; hardware reads when called. ``None``: now.

        Returns
        -------
        Reading
            The value and the clock time of the reading.

        Raises
        ------
        RigStateError
            If the rig is closed.
        RigFaultError
            If the device faults or the reading exceeds the output limit (the
            fault is latched and the actuator made safe).
        """
        with self._lock:
            if self._state is RigState.CLOSED:
                raise RigStateError(self._refusal("read"))
            self._at = _check_instant(at)
            try:
                reading = self._read_output()
                if self._state is not RigState.FAULTED:
                    self._check_limit(reading)
            except RigFaultError as exc:
                self._latch(str(exc))
                raise
            finally:
                self._at = None
            return reading

    def set_channel(self, name: str, value: float, *, at: float | None = None) -> float:
        """Set a further input (:attr:`RigInfo.further_inputs`): a kit's heater 2.

        Parameters
        ----------
        name : str
            The channel's declared name (``"q2"``).
        value : float
            Its level, within the channel's range.
        at : float, optional
            The scheduled sample instant (see :meth:`apply`).

        Returns
        -------
        float
            The level set.

        Raises
        ------
        InvalidParameterError
            For a channel the rig does not declare, or a level outside its range.
        RigStateError
            If the rig is closed, or not POWERED and ``value`` is not the
            channel's default (an idle rig heats nothing).
        RigFaultError
            If the device faults (the fault is latched, the rig made safe).
        """
        with self._lock:
            channel = self._info.inputs.get(name)
            level = self._info.further_level(name, value)
            assert channel is not None  # further_level refuses an undeclared name
            if self._state is RigState.CLOSED or (
                self._state is not RigState.POWERED and level != channel.default
            ):
                raise RigStateError(self._refusal(f"set {name}"))
            self._at = _check_instant(at)
            try:
                return self._set_further_input(name, level)
            except RigFaultError as exc:
                self._latch(str(exc))
                raise
            finally:
                self._at = None

    def level(self, name: str) -> float:
        """The further input ``name``'s level now (its default unless set while powered).

        Raises
        ------
        InvalidParameterError
            For a channel the rig does not declare.
        """
        with self._lock:
            if name not in self._info.inputs:
                self._info.further_level(name, math.nan)  # raises, naming what the rig has
            return self._further_level(name)

    def clear_fault(self) -> None:
        """Acknowledge a latched fault and return to IDLE.

        No effect when no fault is latched.

        Raises
        ------
        RigFaultError
            If the cause persists (the fault stays latched).
        RigStateError
            If the rig is closed.
        """
        with self._lock:
            if self._state is RigState.CLOSED:
                raise RigStateError(self._refusal("clear a fault"))
            if self._state is not RigState.FAULTED:
                return
            self._check_fault_cleared()
            self._fault = None
            self._transition(RigState.IDLE)

    def close(self) -> None:
        """Make the actuator safe and release the rig (idempotent, never raises)."""
        with self._lock:
            if self._state is RigState.CLOSED:
                return
            try:
                self._make_safe()
            finally:
                self._transition(RigState.CLOSED)
                self._release()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self._info.name!r} {self._state.value}>"

    # -- helpers for subclasses ------------------------------------------------

    def _instant(self) -> float:
        """The instant the operation in progress is for.

        The sample instant passed to :meth:`read` or :meth:`apply`, else the
        clock's now (also for power-off, faults and anything else).
        """
        at = self._at
        return self._clock.now() if at is None else at

    def _latch(self, reason: str) -> None:
        """Latch a fault: record the reason, make the actuator safe, enter FAULTED."""
        with self._lock:
            self._make_safe()
            if self._state in (RigState.IDLE, RigState.POWERED):
                self._fault = reason
                self._transition(RigState.FAULTED)

    def _check_limit(self, reading: Reading) -> None:
        limit = self._info.output_limit
        if limit is not None and not reading.value <= limit:
            raise RigFaultError(
                f"{self._info.name}: output {reading.value:.3f} {self._info.output_unit} "
                f"exceeds the limit of {limit:g} {self._info.output_unit}; actuator switched off"
            )
        # Every further output has its own limit (a kit's sensor 2 watches heater 2).
        for channel in self._info.further_outputs:
            value = reading.further.get(channel.name)
            if channel.limit is not None and value is not None and not value <= channel.limit:
                raise RigFaultError(
                    f"{self._info.name}: output {channel.name} {value:.3f} {channel.unit} "
                    f"exceeds the limit of {channel.limit:g} {channel.unit}; "
                    "actuators switched off"
                )

    def _transition(self, new: RigState) -> None:
        if new not in _TRANSITIONS[self._state]:
            raise RigStateError(
                f"{self._info.name}: illegal state transition {self._state.value} -> {new.value}"
            )
        self._state = new

    def _refusal(self, action: str) -> str:
        name = self._info.name
        if self._state is RigState.CLOSED:
            return f"cannot {action}: rig {name!r} is closed"
        if self._state is RigState.FAULTED:
            return f"cannot {action}: rig {name!r} is faulted ({self._fault})"
        return f"cannot {action}: rig {name!r} is {self._state.value}; call power_on() first"


def _check_instant(at: float | None) -> float | None:
    if at is None:
        return None
    try:
        value = float(at)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise InvalidParameterError(f"a sample instant must be a finite clock time, got {at!r}")
    return value
