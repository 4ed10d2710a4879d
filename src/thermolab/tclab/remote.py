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

from thermolab.client import Lab, LabRequestError, Turn
from thermolab.tclab.labtime import labtime

__all__ = ["ENV_RIG", "SecondHeaterError", "TCLab"]

ENV_RIG = "THERMOLAB_RIG"


class SecondHeaterError(NotImplementedError):
    """The rig has one heater and one sensor: ``Q2``/``T2`` do not exist there."""


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


def _pick_rig(rigs: list[dict[str, Any]], simulated: bool | None) -> str:
    if not rigs:
        raise LabRequestError("GET", "/api/rigs", None, "no_rigs", "the lab has no rigs")
    if simulated is True:
        twins = [r for r in rigs if r["kind"] == "sim"]
        heated = [r for r in twins if r["input"]["unit"] == "%"]
        if not twins:
            raise LabRequestError(
                "GET",
                "/api/rigs",
                None,
                "no_twin",
                "the lab has no simulated rig for connected=False",
            )
        return str((heated or twins)[0]["id"])
    kits = [r for r in rigs if r["kind"] == "tclab"]
    return str((kits or rigs)[0]["id"])


class TCLab:
    """The TCLab kit's interface on a lab rig: ``T1``, ``Q1``, ``LED``, ``close``...

    Parameters
    ----------
    port : str
        Ignored (the kit's serial port); kept so that ``TCLab()`` calls run unchanged.
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
    """

    _simulated: ClassVar[bool | None] = None  # set by ``setup(connected=...)``
    heaters = 1
    """The lab's rigs drive one heater and read one sensor (``Q1``/``T1``)."""

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
        self.debug = debug
        self._turn: Turn | None = None
        self._q1 = 0.0
        self._led = 0.0
        self.connected = False
        self.lab = Lab(url, token)
        try:
            rigs = self.lab.rigs()
            self.rig_id = rig or os.environ.get(ENV_RIG) or _pick_rig(rigs, self._simulated)
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
            self._low = float(info["input"]["min"])
            self._high = float(info["input"]["max"])
            # The rig's own speed-up (a twin's: its teacher's setting; unknown on a rig host: 1).
            self.speedup = float(info.get("speedup") or 1.0)
            labtime.set_rate(self.speedup)
            _install_exit_hooks()
            self._turn = self.lab.control(self.rig_id, timeout=wait)
        except BaseException:
            self.lab.close()
            raise
        _open.add(self)
        self.connected = True
        self.version = f"ThermoLab {self.lab.info.get('version')} (API {self.lab.info.get('api')})"
        speed = f" at {self.speedup:g}x" if self.speedup != 1 else ""
        print(f"TCLab connected to rig {self.rig_id!r}{speed} of the lab at {self.lab.url}.")

    # -- the kit's interface ---------------------------------------------------------------

    def _held(self) -> Turn:
        if self._turn is None or not self.connected:
            raise RuntimeError("this TCLab is closed; make a new one (TCLab()) to use the rig")
        if self._turn.lost is not None:
            raise RuntimeError(f"the turn at rig {self.rig_id!r} ended: {self._turn.lost}")
        return self._turn

    def _second(self, name: str) -> SecondHeaterError:
        return SecondHeaterError(
            f"rig {self.rig_id!r} has one heater and one sensor: {name} does not exist "
            "there (use Q1 and T1)"
        )

    @property
    def T1(self) -> float:
        """Temperature of sensor 1 (the rig's output, in its unit), read now."""
        reading = self._held().read()
        if reading.y is None:
            raise RuntimeError(f"rig {self.rig_id!r} gave no reading (is it powered?)")
        if self.debug:
            print(f"T1 -> {reading.y}")
        return float(reading.y)

    @property
    def T2(self) -> float:
        """Sensor 2: not on the lab's rigs (:class:`SecondHeaterError`)."""
        raise self._second("T2")

    def Q1(self, val: float | None = None) -> float:
        """Set heater 1 to ``val`` (clipped to the rig's range, as the kit clips); return it."""
        if val is None:
            return self._q1
        value = float(val)
        if not math.isfinite(value):
            raise ValueError(f"Q1 must be a finite number; got {val!r}")
        value = min(max(value, self._low), self._high)
        self._held().set_input(value)
        if self.debug:
            print(f"Q1 <- {value}")
        self._q1 = value
        return value

    def Q2(self, val: float | None = None) -> float:
        """Heater 2: not on the lab's rigs (:class:`SecondHeaterError`)."""
        raise self._second("Q2")

    @property
    def U1(self) -> float:
        """Heater 1, as a property."""
        return self._q1

    @U1.setter
    def U1(self, val: float) -> None:
        self.Q1(val)

    @property
    def U2(self) -> float:
        """Heater 2: not on the lab's rigs."""
        raise self._second("U2")

    @U2.setter
    def U2(self, val: float) -> None:
        raise self._second("U2")

    def LED(self, val: float = 100) -> float:
        """The kit's LED: the lab's rigs have none; the value is kept and returned."""
        self._led = min(max(float(val), 0.0), 100.0)
        return self._led

    def scan(self) -> tuple[float, float, float, float]:
        """``(T1, T2, Q1, Q2)``; the channels a one-heater rig lacks are NaN."""
        return (self.T1, math.nan, self._q1, math.nan)

    @property
    def sources(self) -> list[tuple[str, Callable[[], float]]]:
        """``(name, function)`` pairs for a :class:`~thermolab.tclab.Historian`."""
        return [("T1", lambda: self.T1), ("Q1", self.Q1)]

    def close(self) -> None:
        """Heater off, turn released (the lab makes the rig safe); idempotent."""
        if not self.connected:
            return
        self.connected = False
        _open.discard(self)
        turn, self._turn = self._turn, None
        try:
            if turn is not None and turn.held:
                # A turn already gone is fine: the lab put the rig at its safe input then.
                with contextlib.suppress(LabRequestError):
                    turn.set_input(min(max(0.0, self._low), self._high))
        finally:
            if turn is not None:
                turn.release()
            self.lab.close()
        print("TCLab disconnected successfully.", file=sys.stderr)

    def __enter__(self) -> TCLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
