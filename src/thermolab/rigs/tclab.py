"""Driver for a TCLab kit (firmware 2.0.1) over USB serial.

:class:`TCLabRig` drives a TCLab kit as a rig: heater 1 and sensor 1 are its
primary pair (input 0-100 % of heater power, output °C); heater 2 is its
further input ``q2`` (:meth:`~thermolab.rigs.base.BaseRig.set_channel`, off at
rest) and sensor 2 its further output ``t2`` (read with sensor 1 at every
reading). It speaks the
firmware 2.0.1 protocol as stated in NOTES.md §6 through pyserial: 115200 baud,
``CMD value\\r\\n`` commands, one reply line per command ending in ``\\r\\n``.

The stock firmware has no over-temperature cut-off and no watchdog, so the
driver provides both on the host, and arms a watchdog in the kit itself when
the kit runs ThermoLab's watchdog sketch (``firmware/tclab_watchdog``):

* at connection the driver sends ``WDOG n`` (``firmware_watchdog`` seconds).
  The sketch answers ``Watchdog n s`` and from then on switches both heaters
  off by itself after ``n`` seconds without a command, whatever happened to
  the host; :attr:`TCLabRig.firmware_watchdog` says ``n``. The stock firmware
  treats ``WDOG`` as an unknown command: it switches the heaters off (they are
  off already at that point) and echoes ``WDOG``; the driver then records
  ``None`` and relies on the host-side guards below;

* a reading of either sensor above ``max_temperature`` (or an implausibly low
  one, the sign of a disconnected sensor) switches both heaters off and
  latches a fault;
* a watchdog thread switches the heaters off and latches a fault when the host
  has neither applied an input nor read the sensor for ``watchdog`` seconds of
  the rig's clock while a heater is on;
* the heaters are switched off when the process ends: on normal exit and
  after an unhandled exception (``atexit``), and on SIGTERM and SIGINT (a
  handler switches every open kit off at once, then lets the process unwind
  normally, so ``with`` blocks and ``finally`` clauses still run). SIGKILL
  cannot be caught: with the stock firmware the heater keeps its last setting
  until the board is reset (opening the port again resets it, and ThermoLab
  switches the heaters off on every connection), so a lab that runs
  unattended should run under a supervisor that restarts it, or flash the
  watchdog sketch, which switches the heaters off ``firmware_watchdog``
  seconds after the last command.

Finding and opening the port is :mod:`thermolab.rigs.tclab_port`
(:func:`find_tclab`, :class:`TCLabVersion`, re-exported here), switching
every open kit off when the process ends :mod:`thermolab.rigs.tclab_exit`.

Every exchange has a timeout; a kit that does not answer raises
:class:`~thermolab.errors.RigTimeoutError`, one that answers garbage or
disappears (unplugged) :class:`~thermolab.errors.RigFaultError`, and in each
case the driver makes a best-effort attempt to switch the heaters off. Nothing
waits longer than the timeout.
"""

from __future__ import annotations

import contextlib
import math
import re
import threading
import time
from collections.abc import Sequence

import serial

from thermolab.errors import InvalidParameterError, RigError, RigFaultError, RigTimeoutError
from thermolab.rigs.base import BaseRig
from thermolab.rigs.clock import Clock, RealClock
from thermolab.rigs.contract import InputChannel, OutputChannel, Reading, RigInfo
from thermolab.rigs.tclab_exit import register, unregister
from thermolab.rigs.tclab_port import PORT_ERRORS, TCLabVersion, find_tclab, open_port

__all__ = ["HEATER_2", "TCLabRig", "TCLabVersion", "find_tclab", "kit_sensor_2", "tclab_info"]

#: Below this a TMP36 reading means a broken or disconnected sensor, not a cold room.
_MIN_PLAUSIBLE_TEMPERATURE = -20.0


#: A kit's heater 2: its further input, as the kit and its twin (``sim:kit``) declare it.
HEATER_2 = InputChannel("q2", description="heater 2, % of its power", sensor="t2")


def kit_sensor_2(max_temperature: float) -> OutputChannel:
    """A kit's sensor 2, its further output, faulting above ``max_temperature`` °C like sensor 1."""
    return OutputChannel("t2", "degC", float(max_temperature), "sensor 2, on heater 2")


def tclab_info(port: str | None, max_temperature: float = 90.0) -> RigInfo:
    """Return the :class:`RigInfo` of a kit, without opening it.

    Parameters
    ----------
    port : str or None
        The kit's serial port; ``None``: found automatically.
    max_temperature : float
        The over-temperature cut-off (°C), the rig's output limit.

    Returns
    -------
    RigInfo
        Heater 1 in 0-100 % (safe at 0), sensor 1 in °C; heater 2 (``q2``)
        and sensor 2 (``t2``) as further channels.

    Examples
    --------
    >>> info = tclab_info("/dev/ttyACM0")
    >>> info.name, info.input_range, info.output_limit
    ('TCLab on /dev/ttyACM0', (0.0, 100.0), 90.0)
    >>> list(info.inputs), list(info.outputs)
    (['q2'], ['t2'])
    """
    return RigInfo(
        name=f"TCLab on {port}" if port is not None else "TCLab (found automatically)",
        kind="tclab",
        input_min=0.0,
        input_max=100.0,
        input_unit="%",
        output_unit="degC",
        safe_input=0.0,
        output_limit=float(max_temperature),
        description="A TCLab kit: heaters 1 and 2 (0-100 %), sensors 1 and 2 (°C).",
        further_inputs=(HEATER_2,),
        further_outputs=(kit_sensor_2(max_temperature),),
    )


class TCLabRig(BaseRig):
    """A TCLab kit as a rig: heater 1 (0-100 %) in, sensor 1 (°C) out; heater 2, sensor 2 further.

    Parameters
    ----------
    port : str, optional
        Serial port (``/dev/ttyACM0``, ``COM3``); ``None``: auto-detect with
        :func:`find_tclab`.
    clock : Clock, optional
        Clock that timestamps readings and runs the watchdog (default
        :class:`~thermolab.rigs.clock.RealClock`).
    timeout : float
        Seconds to wait for each reply (default 1.0).
    reset_wait : float
        Seconds to wait after opening the port for the board's reset (2.0).
    max_temperature : float
        Over-temperature cut-off of each sensor in °C (default 90).
    watchdog : float or None
        Seconds (of ``clock``) of host silence after which a heater that is
        on is switched off and a fault latched (default 10); ``None``: off.
    baudrate : int
        115200 for firmware 2.x.
    candidates : sequence of str, optional
        Ports to probe when ``port`` is ``None`` (default: all).
    min_firmware : tuple of int
        Oldest accepted firmware version (default ``(2, 0, 0)``); version 3
        and later are refused too (an unknown protocol).
    firmware_watchdog : int or None
        Seconds of silence after which the watchdog sketch switches the
        heaters off (1-3600, default 15: longer than the host-side
        ``watchdog``, so the host's guard acts first while it lives); ``None``:
        do not ask (the sketch keeps its power-on default).

    Attributes
    ----------
    firmware_watchdog : int or None
        The period the kit's own watchdog was armed with; ``None`` when the
        kit has none (stock firmware) or it was not asked.

    Raises
    ------
    RigError
        If the port cannot be opened, no kit is found, or the firmware is not
        supported.
    RigTimeoutError
        If the kit does not answer.
    InvalidParameterError
        For a non-positive timeout or watchdog.

    Notes
    -----
    A reading's time is the clock's time halfway between sending ``T1`` and
    receiving the reply to ``T2``. ``apply`` (and ``set_channel("q2", ...)``)
    returns the heater value the firmware echoes (clipped, three decimals).
    """

    def __init__(
        self,
        port: str | None = None,
        *,
        clock: Clock | None = None,
        timeout: float = 1.0,
        reset_wait: float = 2.0,
        max_temperature: float = 90.0,
        watchdog: float | None = 10.0,
        baudrate: int = 115200,
        candidates: Sequence[str] | None = None,
        min_firmware: tuple[int, int, int] = (2, 0, 0),
        firmware_watchdog: int | None = 15,
    ) -> None:
        if not (math.isfinite(timeout) and timeout > 0):
            raise InvalidParameterError(f"timeout must be a positive number, got {timeout!r}")
        if not (math.isfinite(reset_wait) and reset_wait >= 0):
            raise InvalidParameterError(f"reset_wait must be a number >= 0, got {reset_wait!r}")
        if watchdog is not None and not (math.isfinite(watchdog) and watchdog > 0):
            raise InvalidParameterError(
                f"watchdog must be a positive number of seconds or None, got {watchdog!r}"
            )
        if firmware_watchdog is not None and not (
            isinstance(firmware_watchdog, int) and 1 <= firmware_watchdog <= 3600
        ):
            raise InvalidParameterError(
                "firmware_watchdog must be a whole number of seconds from 1 to 3600 or None, "
                f"got {firmware_watchdog!r}"
            )
        if not math.isfinite(max_temperature):
            raise InvalidParameterError(
                f"max_temperature must be a finite number, got {max_temperature!r}"
            )
        clock = clock if clock is not None else RealClock()
        if port is None:
            port, _ = find_tclab(
                candidates, baudrate=baudrate, timeout=timeout, reset_wait=reset_wait
            )
        self.port = port
        self._timeout = timeout
        self._link: serial.Serial | None = None
        self._desync = False
        self._sync_count = 0
        self._heater = 0.0
        self._heater_2 = 0.0
        self._last_host = clock.now()
        self._watchdog_period = watchdog
        self._watchdog_stop = threading.Event()
        self._watchdog_thread: threading.Thread | None = None
        super().__init__(
            tclab_info(port, max_temperature),
            clock,
        )
        self._link = open_port(port, baudrate, timeout)
        try:
            time.sleep(reset_wait)  # a physical board reset, not simulated time
            reply = self._exchange("VER")
            version = TCLabVersion.parse(reply)
            if version is None:
                raise RigError(f"{port} is not a TCLab: it answered {reply!r} to VER")
            if not (min_firmware <= (version.major, version.minor, version.patch)) or (
                version.major >= 3
            ):
                raise RigError(
                    f"TCLab firmware {version.text} on {port} is not supported; "
                    f"this driver needs 2.x (at least {'.'.join(map(str, min_firmware))}): "
                    "flash TCLab firmware 2.0.1"
                )
            self.version = version
            self._switch_off()
            self.firmware_watchdog = (
                self._arm_firmware_watchdog(firmware_watchdog)
                if firmware_watchdog is not None
                else None
            )
        except BaseException:
            self._close_link()
            raise
        if watchdog is not None:
            self._watchdog_thread = threading.Thread(
                target=self._watch, name=f"tclab-watchdog {port}", daemon=True
            )
            self._watchdog_thread.start()
        register(self)

    # -- serial exchange ---------------------------------------------------------

    def _exchange(self, command: str) -> str:
        """Send one command and return its reply line, within the timeout."""
        with self._lock:
            if self._desync:
                self._resync()
            # Until a well-formed reply arrives, a late answer may still be on its way.
            self._desync = True
            raw = self._send_and_read(command)
            try:
                reply = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise RigFaultError(
                    f"TCLab on {self.port} answered garbage {raw!r} to {command!r}; "
                    "heaters switched off"
                ) from None
            self._desync = False
            return reply

    def _send_and_read(self, command: str) -> bytes:
        link = self._link
        if link is None:
            raise RigFaultError(f"TCLab on {self.port}: the port is closed")
        try:
            link.reset_input_buffer()  # drop replies that arrived after an earlier timeout
            link.write(f"{command}\r\n".encode("ascii"))
            raw = bytes(link.read_until(b"\r\n"))
        except serial.SerialTimeoutException:
            raise RigTimeoutError(
                f"TCLab on {self.port}: could not send {command!r} within "
                f"{self._timeout:g} s; heaters switched off"
            ) from None
        except PORT_ERRORS as exc:
            raise RigFaultError(
                f"TCLab on {self.port} is gone (unplugged?) during {command!r}: {exc}"
            ) from None
        if not raw.endswith(b"\r\n"):
            if raw:
                raise RigFaultError(
                    f"TCLab on {self.port} answered an incomplete line {raw!r} to "
                    f"{command!r}; heaters switched off"
                )
            raise RigTimeoutError(
                f"TCLab on {self.port} did not answer {command!r} within "
                f"{self._timeout:g} s; heaters switched off"
            )
        return raw

    def _resync(self) -> None:
        """Realign replies with commands after a failed exchange.

        A reply that arrives after its timeout would otherwise be taken as the
        answer to the next command. The firmware echoes an unknown command
        upper-cased, so an unknown command carrying a fresh number is a marker:
        every line before its echo is stale. Unknown commands also switch the
        heaters off, which is right here: a failed exchange has latched a fault.
        """
        self._sync_count += 1
        marker = f"SYNC{self._sync_count}"
        link = self._link
        deadline = time.monotonic() + self._timeout
        raw = self._send_and_read(marker)
        while raw.strip() != marker.encode("ascii"):
            if time.monotonic() > deadline or link is None:
                raise RigTimeoutError(
                    f"TCLab on {self.port} did not echo {marker!r} within {self._timeout:g} s; "
                    "its replies cannot be trusted; heaters switched off"
                )
            try:
                raw = bytes(link.read_until(b"\r\n"))
            except PORT_ERRORS as exc:
                raise RigFaultError(
                    f"TCLab on {self.port} is gone (unplugged?) during {marker!r}: {exc}"
                ) from None
        self._heater = self._heater_2 = 0.0
        self._desync = False

    def _number(self, command: str) -> float:
        reply = self._exchange(command)
        try:
            value = float(reply)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            self._desync = True
            raise RigFaultError(
                f"TCLab on {self.port} answered {reply!r} to {command!r}, not a number; "
                "heaters switched off"
            )
        return value

    def _arm_firmware_watchdog(self, seconds: int) -> int | None:
        """Ask the kit for its own watchdog; return the period it armed, or ``None``."""
        reply = self._exchange(f"WDOG {seconds}")
        match = re.fullmatch(r"Watchdog (\d+) s", reply.strip())
        if match is None:
            # Stock firmware: WDOG is unknown, so it echoed it and switched the heaters off
            # (they are off already). The host-side guards are all there is.
            self._heater = self._heater_2 = 0.0
            return None
        return int(match.group(1))

    def _switch_off(self) -> None:
        reply = self._exchange("X")
        if reply.upper() != "STOP":
            self._desync = True
            raise RigFaultError(
                f"TCLab on {self.port} answered {reply!r} to X instead of 'Stop'; "
                "heaters may still be on"
            )
        self._heater = self._heater_2 = 0.0

    # -- hooks ----------------------------------------------------------------------

    def _apply_input(self, u: float) -> float:
        self._heater = self._set_heater(1, u)
        return self._heater

    def _set_further_input(self, name: str, value: float) -> float:
        # HEATER_2 is the one further input the kit declares.
        self._heater_2 = self._set_heater(2, value)
        return self._heater_2

    def _further_level(self, name: str) -> float:
        return self._heater_2

    def _set_heater(self, n: int, percent: float) -> float:
        """Send ``Qn``; return the level the firmware echoes, or fault on a wrong echo."""
        self._last_host = self.clock.now()
        echo = self._number(f"Q{n} {percent:.3f}")
        if abs(echo - percent) > 0.0015:
            self._desync = True
            raise RigFaultError(
                f"TCLab on {self.port} echoed {echo!r} for heater {n} set to {percent:.3f}; "
                "heaters switched off"
            )
        return echo

    def _read_output(self) -> Reading:
        before = self.clock.now()
        self._last_host = before
        value = self._temperature(1)
        value_2 = self._temperature(2)
        t = 0.5 * (before + self.clock.now())
        return Reading(value, t, {"t2": value_2})

    def _temperature(self, n: int) -> float:
        value = self._number(f"T{n}")
        if value < _MIN_PLAUSIBLE_TEMPERATURE:
            raise RigFaultError(
                f"TCLab on {self.port}: sensor {n} reads {value:.3f} °C, below "
                f"{_MIN_PLAUSIBLE_TEMPERATURE:g} °C: disconnected or broken sensor; "
                "heaters switched off"
            )
        return value

    def _make_safe(self) -> None:
        if self._link is None:
            return
        try:
            self._switch_off()
        except Exception:
            # The kit did not confirm; still try the explicit heater commands.
            self._emergency_off()

    def _release(self) -> None:
        self._watchdog_stop.set()
        thread = self._watchdog_thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)
        self._close_link()
        unregister(self)

    def _close_link(self) -> None:
        link, self._link = self._link, None
        if link is not None:
            with contextlib.suppress(Exception):
                link.close()

    def _emergency_off(self) -> None:
        """Write heater-off commands without waiting for replies (signal-handler safe)."""
        link = self._link
        if link is None:
            return
        self._desync = True  # their replies will arrive unread
        with contextlib.suppress(Exception):
            link.write(b"Q1 0\r\nQ2 0\r\nX\r\n")
            link.flush()

    # -- watchdog ---------------------------------------------------------------------

    @property
    def heater(self) -> float:
        """Heater 1 setting as last confirmed by the kit, percent."""
        return self._heater

    def _watch(self) -> None:
        assert self._watchdog_period is not None
        period = self._watchdog_period
        # Poll often in real time: with a fast virtual clock, seconds pass quickly.
        while not self._watchdog_stop.wait(0.02):
            silent_for = self.clock.now() - self._last_host
            heating = self._heater > 0.0 or self._heater_2 > 0.0
            if self.powered and heating and silent_for > period:
                with self._lock:
                    if self.powered and self.clock.now() - self._last_host > period:
                        self._latch(
                            f"TCLab on {self.port}: watchdog: no command from the host for "
                            f"{silent_for:.1f} s (limit {period:g} s); heaters switched off"
                        )

    def _check_fault_cleared(self) -> None:
        reading = self._read_output()
        self._check_limit(reading)
