# ruff: noqa: N802  (T1, Q1, LED... are the kit's names, which notebooks call)
"""``TCLab`` backed by a lab rig over the network (through :mod:`thermolab.client`).

Connecting asks for control of the rig and waits in its queue, saying the
place; the turn is then kept alive while the script runs. Every way out —
:meth:`TCLab.close`, the end of a ``with`` block (normally or by an
exception, Ctrl-C included), the end of the interpreter (``atexit``), or
SIGTERM/SIGHUP (turned into ``SystemExit`` so that the same clean-up runs) —
sets the heater to 0 and releases the turn, and the lab puts the rig at its
safe input for the next user.

Where the lab is: ``url``/``token``/``rig`` arguments, else the environment
variables ``THERMOLAB_URL``, ``THERMOLAB_TOKEN`` and ``THERMOLAB_RIG``
(default rig: the first kit, else the first rig; with ``setup(connected=False)``
the first simulated rig).
"""

from __future__ import annotations

import atexit
import contextlib
import math
import os
import signal
import sys
import threading
import weakref
from collections.abc import Callable
from types import FrameType
from typing import Any, ClassVar

from thermolab.client import Lab, LabRequestError, Reading, Turn
from thermolab.tclab.kit_errors import (
    AlreadyConnectedError,
    NotOnThisRigError,
    PortError,
    SecondHeaterError,
)
from thermolab.tclab.labtime import labtime
from thermolab.tclab.rig_choice import ENV_RIG, check_kit, describe_rig, pick_rig

__all__ = ["KIT_P1", "TCLab"]

KIT_P1 = 200.0
"""Heater 1's PWM limit (counts of 255) at which a kit's 100 % is a lab rig's 100 %."""

KIT_P2 = 100.0
"""Heater 2's PWM limit at which a kit's 100 % is a lab rig's heater 2 at 100 %."""

HEATER_2, SENSOR_2 = "q2", "t2"
"""The names a rig declares the kit's heater 2 and sensor 2 by (``thermolab.rigs.tclab``)."""

_open: weakref.WeakSet[TCLab] = weakref.WeakSet()
_guard = threading.Lock()
_installed = False


def _close_all() -> None:
    for kit in list(_open):
        kit.close()


def _exit_on_signal(signum: int, frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)  # unwinds ``with`` blocks; atexit then closes the rest


def _install_exit_hooks() -> None:
    global _installed
    with _guard:
        if _installed:
            return
        _installed = True
        atexit.register(_close_all)
        if threading.current_thread() is threading.main_thread():
            for name in ("SIGTERM", "SIGHUP"):
                number = getattr(signal, name, None)
                # Only where nobody chose a handler already (a notebook kernel, a framework).
                if number is not None and signal.getsignal(number) is signal.SIG_DFL:
                    signal.signal(number, _exit_on_signal)


def _channel(reading: Reading, name: str) -> float:
    """A further channel of ``reading`` (NaN if the lab did not know it yet)."""
    value = reading.channels.get(name)
    return math.nan if value is None else float(value)


class TCLab:
    """The TCLab kit's interface on a lab rig: ``T1``, ``Q1``, ``LED``, ``scan``, ``close``...

    Parameters
    ----------
    port : str
        The kit's serial port: a lab rig has none, so only the default ``""``
        is accepted (:class:`PortError`, a ``RuntimeError`` as in ``tclab``).
    debug : bool
        Print each command.
    url, token, rig : str, optional
        The lab, a personal API token and the rig (default: the environment).
    wait : float, optional
        Seconds to wait in the queue (default: as long as it takes).

    Attributes
    ----------
    speedup : float
        The rig's speed-up when it connected (``labtime`` follows it): 1 for
        hardware, a twin's teacher setting (1 when the lab does not know it).
    heaters : int
        2 on a rig with the kit's heater 2 and sensor 2 (a kit, ``sim:kit``), else 1.
    sources : list of (name, callable or None)
        ``T1``, ``T2``, ``Q1``, ``Q2`` from one :meth:`scan`, for a
        :class:`~thermolab.tclab.Historian` (on a one-heater rig ``T2`` and
        ``Q2`` are NaN, so the record has the kit's columns).

    Raises
    ------
    PortError
        For a ``port``.
    NotAKitError
        For a rig that is not a heater in % and a sensor in °C (naming what it has).
    AlreadyConnectedError
        If this process already holds the rig through another open ``TCLab``.
    thermolab.client.LabRequestError
        If the lab cannot be reached ("cannot reach the lab at ...") or refuses.
    """

    _simulated: ClassVar[bool | None] = None  # set by ``setup(connected=...)``

    def __init__(
        self,
        port: str = "",
        debug: bool = False,
        *,
        url: str | None = None,
        token: str | None = None,
        rig: str | None = None,
        wait: float | None = None,
    ) -> None:
        self.connected = False
        if port:
            raise PortError(
                f"TCLab(port={port!r}): a lab rig has no serial port. Leave port out; the rig "
                f"comes from rig= or ${ENV_RIG} (and the lab from url= or $THERMOLAB_URL)"
            )
        self.debug = debug
        self._turn: Turn | None = None
        self._led = 0.0
        self._p1 = KIT_P1
        self._q1 = 0.0  # the last Q1 set, for reading it back under P1 = 0
        self._p2 = KIT_P2
        self._q2 = 0.0
        self.heaters = 1
        self.lab = Lab(url, token)
        try:
            rigs = self.lab.rigs()
            self.rig_id = rig or os.environ.get(ENV_RIG) or pick_rig(rigs, self._simulated)
            info = next((r for r in rigs if r["id"] == self.rig_id), None)
            if info is None:
                known = ", ".join(r["id"] for r in rigs)
                raise LabRequestError(
                    "GET",
                    "/api/rigs",
                    404,
                    "not_found",
                    f"no rig {self.rig_id!r}; the lab has {known}",
                )
            self.info = info
            check_kit(info)
            # Heater 2 and sensor 2 as the rig declares them: both, or the kit's one pair.
            inputs = {a["name"] for a in info.get("actuators") or ()}
            outputs = {o["name"] for o in info.get("outputs") or ()}
            self.heaters = 2 if HEATER_2 in inputs and SENSOR_2 in outputs else 1
            self._key = (self.lab.url, self.rig_id)
            with _guard:
                if any(kit._key == self._key for kit in _open):
                    raise AlreadyConnectedError(
                        f"this process already has an open TCLab on rig {self.rig_id!r} of "
                        f"the lab at {self.lab.url}: close() it (or leave its with-block) first"
                    )
            self._low = float(info["input"]["min"])
            self._high = float(info["input"]["max"])
            # The rig's own speed-up (a twin's: its teacher's setting; unknown on a rig host: 1).
            self.speedup = float(info.get("speedup") or 1.0)
            _install_exit_hooks()
            self._turn = self.lab.control(self.rig_id, timeout=wait)
            held = f"rig {self.rig_id!r} of the lab at {self.lab.url} runs at {self.speedup:g}x"
            self._rate_before = labtime.get_rate()  # the notebook's pace comes back at close()
            labtime.hold(self.speedup, held if self.speedup != 1 else None)
            if self.speedup == 1:
                labtime.set_rate(1)
        except BaseException:
            if self._turn is not None:
                self._turn.release()
            self.lab.close()
            raise
        _open.add(self)
        self.connected = True
        self.version = f"ThermoLab {self.lab.info.get('version')} (API {self.lab.info.get('api')})"
        self.sources: list[tuple[str, Callable[[], Any] | None]] = [
            ("T1", self.scan),
            ("T2", None),
            ("Q1", None),
            ("Q2", None),
        ]
        speed = f" at {self.speedup:g}x" if self.speedup != 1 else ""
        print(f"TCLab connected to rig {self.rig_id!r}{speed} of the lab at {self.lab.url}.")

    # -- the kit's interface ---------------------------------------------------------------

    def _held(self) -> Turn:
        if self._turn is None or not self.connected:
            raise RuntimeError("this TCLab is closed; make a new one (TCLab()) to use the rig")
        self._turn.check()
        return self._turn

    def _request(self, call: Callable[[Turn], Any]) -> Any:
        turn = self._held()
        try:
            return call(turn)
        except LabRequestError as exc:
            # A refusal because the turn just ended says so, by its reason.
            turn.refused(exc)
            turn.check()
            raise

    def _missing(self, name: str) -> SecondHeaterError:
        return SecondHeaterError(
            f"{describe_rig(self.info)}: one heater (Q1, U1, P1) and one sensor (T1), so {name} "
            "does not exist there. The kit's second heater and sensor need a two-heater rig; "
            "scan() and sources give NaN for T2 and Q2 here"
        )

    def _reading(self) -> Reading:
        reading: Reading = self._request(lambda turn: turn.read())
        if reading.y is None:
            raise RuntimeError(f"rig {self.rig_id!r} gave no reading (is it powered?)")
        return reading

    @property
    def T1(self) -> float:
        """Temperature of sensor 1 in °C, read now."""
        value = float(self._reading().y or 0.0)
        if self.debug:
            print(f"T1 -> {value}")
        return value

    @property
    def T2(self) -> float:
        """Temperature of sensor 2 in °C, read now (one-heater rig: :class:`SecondHeaterError`)."""
        self._need_second("T2")
        value = _channel(self._reading(), SENSOR_2)
        if self.debug:
            print(f"T2 -> {value}")
        return value

    def _need_second(self, name: str) -> None:
        if self.heaters < 2:
            raise self._missing(name)

    def _q1_of(self, applied: float | None) -> float:
        # The rig's input is the heater's share of its full power; Q1 is that share under P1.
        if applied is None or self._p1 == 0:
            return self._q1
        return round(float(applied) * KIT_P1 / self._p1, 9)

    def Q1(self, val: float | None = None) -> float:
        """Heater 1 in %: set it to ``val`` clipped to 0–100 (if given); return it, read now.

        Under a ``P1`` below the kit's 200, the rig receives ``Q1 × P1 / 200``
        % of its full heater, as the kit's PWM limit scales its heater.

        Raises
        ------
        ValueError
            For a value that is not a finite number.
        """
        if val is None:
            value = self._q1_of(self._reading().u)
            if self.debug:
                print(f"Q1 -> {value}")
            return value
        value = float(val)
        if not math.isfinite(value):
            raise ValueError(f"Q1 must be a finite number of %; got {val!r}")
        value = min(max(value, self._low), self._high)
        applied = value * self._p1 / KIT_P1
        self._request(lambda turn: turn.set_input(applied))
        self._q1 = value
        if self.debug:
            print(f"Q1 <- {value}")
        return value

    def Q2(self, val: float | None = None) -> float:
        """Heater 2 in %: set it to ``val`` clipped to 0–100 (if given); return it, read now.

        Under a ``P2`` below the kit's 100, the rig receives ``Q2 × P2 / 100`` %
        of heater 2's full power. A one-heater rig: :class:`SecondHeaterError`.

        Raises
        ------
        ValueError
            For a value that is not a finite number.
        """
        self._need_second("Q2")
        if val is None:
            value = self._q2_of(_channel(self._reading(), HEATER_2))
            if self.debug:
                print(f"Q2 -> {value}")
            return value
        value = float(val)
        if not math.isfinite(value):
            raise ValueError(f"Q2 must be a finite number of %; got {val!r}")
        value = min(max(value, 0.0), 100.0)
        applied = value * self._p2 / KIT_P2
        self._request(lambda turn: turn.set_channel(HEATER_2, applied))
        self._q2 = value
        if self.debug:
            print(f"Q2 <- {value}")
        return value

    def _q2_of(self, applied: float) -> float:
        # As _q1_of: the rig's level is heater 2's share of its full power, under P2.
        if math.isnan(applied) or self._p2 == 0:
            return self._q2
        return round(applied * KIT_P2 / self._p2, 9)

    @property
    def U1(self) -> float:
        """Heater 1 in %, as a property (read now)."""
        return self.Q1()

    @U1.setter
    def U1(self, val: float) -> None:
        self.Q1(val)

    @property
    def U2(self) -> float:
        """Heater 2 in %, as a property (read now; a one-heater rig: :class:`SecondHeaterError`)."""
        self._need_second("U2")
        return self.Q2()

    @U2.setter
    def U2(self, val: float) -> None:
        self._need_second("U2")
        self.Q2(val)

    @property
    def P1(self) -> float:
        """Heater 1's PWM limit in counts of 255 (the kit's 200 at the start).

        Setting it clips to 0–255 as the kit does; the lab's rig at 100 % is
        the kit at ``P1 = 200``, so limits up to 200 are applied by scaling
        the heater, and above 200 are refused (:class:`NotOnThisRigError`).
        """
        return self._p1

    @P1.setter
    def P1(self, val: float) -> None:
        limit = min(max(float(val), 0.0), 255.0)
        if limit > KIT_P1:
            raise NotOnThisRigError(
                f"rig {self.rig_id!r}: its full heater is the kit's P1 = {KIT_P1:g} (of 255), "
                f"so P1 = {val!r} (more power than that) cannot be applied; use P1 <= {KIT_P1:g}"
            )
        q1 = self._q1
        self._p1 = limit
        if self.connected:
            self.Q1(q1)  # the heater's power follows its new limit now, as on the kit

    @property
    def P2(self) -> float:
        """Heater 2's PWM limit in counts of 255 (the kit's 100 at the start).

        As :attr:`P1`: up to the kit's 100 applied by scaling heater 2, above
        refused (:class:`NotOnThisRigError`); a one-heater rig: :class:`SecondHeaterError`.
        """
        self._need_second("P2")
        return self._p2

    @P2.setter
    def P2(self, val: float) -> None:
        self._need_second("P2")
        limit = min(max(float(val), 0.0), 255.0)
        if limit > KIT_P2:
            raise NotOnThisRigError(
                f"rig {self.rig_id!r}: its full heater 2 is the kit's P2 = {KIT_P2:g} (of 255), "
                f"so P2 = {val!r} (more power than that) cannot be applied; use P2 <= {KIT_P2:g}"
            )
        q2 = self._q2
        self._p2 = limit
        if self.connected:
            self.Q2(q2)  # heater 2's power follows its new limit now, as on the kit

    def LED(self, val: float = 100) -> float:
        """The kit's LED in %: the lab's rigs have none; ``val`` is clipped to 0–100, returned."""
        self._led = min(max(float(val), 0.0), 100.0)
        return self._led

    def scan(self) -> tuple[float, float, float, float]:
        """``(T1, T2, Q1, Q2)`` from one reading; a one-heater rig's T2 and Q2 are NaN."""
        reading = self._reading()
        t1, q1 = float(reading.y or 0.0), self._q1_of(reading.u)
        if self.heaters < 2:
            return (t1, math.nan, q1, math.nan)
        return (t1, _channel(reading, SENSOR_2), q1, self._q2_of(_channel(reading, HEATER_2)))

    def close(self) -> None:
        """Heater off, turn released (the lab makes the rig safe); idempotent."""
        if not self.connected:
            return
        self.connected = False
        _open.discard(self)
        if labtime.held_by is not None and f"rig {self.rig_id!r}" in labtime.held_by:
            labtime.hold(self.speedup, None)
            labtime.set_rate(self._rate_before)
        turn, self._turn = self._turn, None
        try:
            if turn is not None and turn.held:
                # A turn already gone is fine: the lab put the rig at its safe input then.
                with contextlib.suppress(LabRequestError):
                    turn.set_input(min(max(0.0, self._low), self._high))
                    if self.heaters == 2:
                        turn.set_channel(HEATER_2, 0.0)
        finally:
            if turn is not None:
                turn.release()
            self.lab.close()
        print("TCLab disconnected successfully.", file=sys.stderr)

    def __enter__(self) -> TCLab:
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> None:
        self.close()
