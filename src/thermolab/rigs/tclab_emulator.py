"""A TCLab firmware emulator on a pseudo-terminal, for tests and rehearsal.

:class:`TCLabEmulator` opens a pseudo-terminal pair and answers on it as a
TCLab kit with firmware 2.0.1 does (NOTES.md §6), with the temperatures of the
``tclab`` twin on an injected clock. Anything that opens ``emulator.port``
with pyserial (the :class:`~thermolab.rigs.tclab.TCLabRig` driver, or another
client) talks to it as to a kit. Switches make it misbehave as broken hardware
does: stop answering, answer garbage, or vanish (the pseudo-terminal closes, as
when the cable is pulled).

Protocol (written from the facts in NOTES.md, not from any firmware source):
a command is ASCII, ended by ``\\r`` or ``\\n`` (so the ``\\n`` of a ``\\r\\n``
pair is an empty command and gets no reply), case-insensitive, a name and an
optional numeric value; every reply line ends in ``\\r\\n``.

=========  ===============================================================
``T1``     temperature of sensor 1, °C, three decimals (``T2`` likewise)
``Q1 x``   heater 1 to ``x`` % clipped to 0-100; echoes the clipped value
``R1``     heater 1 read back (``Q2``/``R2`` likewise)
``P1 x``   heater power limit 0-255; echoes the clipped value (stored only)
``LED x``  LED override for 10 s; echoes the value (stored only)
``SCAN``   four lines: T1, T2, Q1, Q2
``VER``    ``TCLab Firmware 2.0.1 Arduino Uno``
``X``      both heaters off; ``Stop``
other      both heaters off; the command name echoed upper-cased
=========  ===============================================================

With ``watchdog_firmware=True`` it is the ThermoLab watchdog sketch
(``firmware/tclab_watchdog``) instead: the same protocol plus ``WDOG n``
(seconds, 0 disarms, at most 3600; reply ``Watchdog n s``), armed at
:data:`FIRMWARE_WATCHDOG_DEFAULT` seconds from power-on; when no command has
arrived for that long, both heaters go off.

The reset of a real board when its port opens (about 2 s of silence) is not
emulated: a pseudo-terminal cannot tell when its far end is opened.

Run ``python -m thermolab.rigs.tclab_emulator`` to get an emulated kit on a
port for a class to rehearse with (``thermolab run --rig tclab:PORT``).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import select
import termios
import threading
import tty
from collections.abc import Sequence
from types import TracebackType
from typing import Self

from thermolab.rigs.clock import Clock, RealClock, make_clock
from thermolab.rigs.twin import TwinRig

__all__ = ["FIRMWARE_WATCHDOG_DEFAULT", "TCLabEmulator", "main"]

FIRMWARE_WATCHDOG_DEFAULT = 30
"""Seconds the watchdog sketch waits for a command after power-on before heaters go off."""


class TCLabEmulator:
    """An emulated TCLab kit (firmware 2.0.1) on a pseudo-terminal.

    Parameters
    ----------
    clock : Clock, optional
        The clock of the thermal model (default :class:`RealClock`). Share a
        :class:`~thermolab.rigs.clock.VirtualClock` with the driver under test
        so that no test waits for the kit to heat.
    seed : int, optional
        Seed of the sensors' noise.
    board : str
        Board name in the ``VER`` reply.
    version : str
        Firmware version in the ``VER`` reply.
    realism : bool
        ``False``: noise-free, unquantised temperatures (exact checks in tests).
    ambient : float
        Ambient temperature in °C (both sensors start there).
    watchdog_firmware : bool
        Emulate the ThermoLab watchdog sketch (``WDOG``) rather than the stock
        firmware.

    Attributes
    ----------
    port : str
        Path of the pseudo-terminal to open (``/dev/pts/N``).
    commands : list of str
        Every command received (upper-cased, stripped), in order.
    silent : bool
        When set, commands are read and obeyed but never answered.
    garbage : bool or str
        ``True``: every reply is replaced by a line of bytes that are not
        ASCII; a string: every reply is replaced by that text (an answer that
        is well-formed but wrong).
    reply_delay : float
        Seconds of real time to wait before each reply (a slow kit, for a
        demonstration; tests use ``hold_replies``, which does not depend on
        how fast the machine is).
    hold_replies : bool
        When set, commands are obeyed but their replies are kept back (a
        stalled kit: the host times out). When cleared again, everything kept
        back is sent in front of the reply to the next command — late answers
        that arrive just as the host asks something else, the case a driver
        must not take for its answer. Deterministic: no timing is involved.
    sensor_disconnected : bool
        When set, both sensors read -50.000 °C, what a TMP36 channel reads at
        ADC code 0 (the sensor unplugged).
    watchdog_period : int
        The watchdog sketch's period in seconds (0: disarmed; stock firmware: 0).
    watchdog_trips : int
        How often the watchdog switched the heaters off.

    Examples
    --------
    >>> import serial
    >>> from thermolab.rigs.clock import VirtualClock
    >>> with TCLabEmulator(clock=VirtualClock(), seed=0) as emulator:
    ...     with serial.Serial(emulator.port, 115200, timeout=2) as port:
    ...         _ = port.write(b"VER\\r\\n")
    ...         port.readline()
    b'TCLab Firmware 2.0.1 Arduino Uno\\r\\n'
    """

    def __init__(
        self,
        *,
        clock: Clock | None = None,
        seed: int | None = None,
        board: str = "Arduino Uno",
        version: str = "2.0.1",
        realism: bool = True,
        ambient: float = 21.0,
        watchdog_firmware: bool = False,
    ) -> None:
        self.clock: Clock = clock if clock is not None else RealClock()
        self.watchdog_firmware = watchdog_firmware
        self.watchdog_period = FIRMWARE_WATCHDOG_DEFAULT if watchdog_firmware else 0
        self.watchdog_trips = 0
        self._last_command = self.clock.now()
        self.board = board
        self.version = version
        self.commands: list[str] = []
        self.silent = False
        self.garbage: bool | str = False
        self.sensor_disconnected = False
        self.reply_delay = 0.0
        self.hold_replies = False
        self._held: list[bytes] = []
        self._lock = threading.Lock()
        seeds = [None, None] if seed is None else [seed, seed + 1]
        # The emulator is the kit, not the host: no over-temperature limit of its own.
        self._heaters = [
            TwinRig(
                "tclab",
                clock=self.clock,
                seed=s,
                realism=realism,
                output_limit=None,
                ambient=ambient,
            )
            for s in seeds
        ]
        for heater in self._heaters:
            heater.power_on()
        self._q = [0.0, 0.0]
        self._p = [255.0, 255.0]
        self._led = 0.0
        self._master, self._slave = os.openpty()
        # Raw mode before anyone opens the port: no echo, no line editing, no CR/LF mapping.
        tty.setraw(self._slave, termios.TCSANOW)
        self.port = os.ttyname(self._slave)
        self._vanished = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="tclab-emulator", daemon=True)
        self._thread.start()

    # -- inspection ---------------------------------------------------------------

    def check_watchdog(self) -> None:
        """Switch the heaters off if the watchdog sketch's period passed without a command.

        The firmware checks in its main loop; the emulator checks before every
        command, every 20 ms of its serving thread, and whenever a test looks
        at a heater (so a test on a virtual clock needs no real waiting).
        """
        with self._lock:
            self._check_watchdog()

    def _check_watchdog(self) -> None:
        if self.watchdog_period <= 0:
            return
        if self.clock.now() - self._last_command >= self.watchdog_period:
            if any(q > 0.0 for q in self._q):
                self._all_off()
                self.watchdog_trips += 1
            self._last_command = self.clock.now()  # as the sketch: re-armed after tripping

    def heater(self, n: int) -> float:
        """Return the setting of heater ``n`` (1 or 2) in percent."""
        self.check_watchdog()
        with self._lock:
            return self._q[self._index(n)]

    def power_limit(self, n: int) -> float:
        """Return the power limit (0-255) of heater ``n`` (1 or 2)."""
        with self._lock:
            return self._p[self._index(n)]

    def temperature(self, n: int) -> float:
        """Return the noise-free temperature of sensor ``n`` (1 or 2) now, °C."""
        with self._lock:
            return self._heaters[self._index(n)].true_output()

    @property
    def vanished(self) -> bool:
        """``True`` once :meth:`vanish` or :meth:`close` has run."""
        return self._vanished

    # -- misbehaviour ----------------------------------------------------------------

    def vanish(self) -> None:
        """Close the pseudo-terminal, as if the kit were unplugged."""
        self.close()

    # -- lifecycle --------------------------------------------------------------------

    def close(self) -> None:
        """Stop answering and close the pseudo-terminal (idempotent)."""
        if self._vanished:
            return
        self._vanished = True
        self._stop.set()
        self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        for heater in self._heaters:
            heater.close()

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
        return f"TCLabEmulator(port={self.port!r})"

    # -- protocol -----------------------------------------------------------------------

    @staticmethod
    def _index(n: int) -> int:
        if n not in (1, 2):
            raise ValueError(f"a TCLab has heaters and sensors 1 and 2, not {n!r}")
        return n - 1

    def _serve(self) -> None:
        pending = b""
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], 0.02)
                if not ready:
                    self.check_watchdog()
                    continue
                chunk = os.read(self._master, 4096)
            except OSError:
                return  # closed under us
            pending += chunk
            # A command ends at CR or LF; what follows the last terminator waits for more.
            *lines, pending = pending.replace(b"\r", b"\n").split(b"\n")
            for line in lines:
                command = line.decode("ascii", errors="replace").strip()
                if not command:
                    continue  # the LF of a CRLF pair: no reply
                replies = self._execute(command)
                if self.silent:
                    continue
                if isinstance(self.garbage, str):
                    replies = [self.garbage] * len(replies)
                elif self.garbage:
                    replies = ["\x00\xff\xfe?\x93"]
                payload = "".join(f"{r}\r\n" for r in replies).encode("latin-1")
                if self.hold_replies:
                    self._held.append(payload)
                    continue
                if self._held:
                    payload = b"".join(self._held) + payload
                    self._held.clear()
                if self.reply_delay > 0.0 and self._stop.wait(self.reply_delay):
                    return
                with contextlib.suppress(OSError):
                    os.write(self._master, payload)

    def _execute(self, command: str) -> list[str]:
        name, _, argument = command.upper().partition(" ")
        argument = argument.strip()
        with self._lock:
            self._check_watchdog()
            self._last_command = self.clock.now()
            self.commands.append(command.upper())
            if name in ("T1", "T2"):
                return [self._temperature(int(name[1]))]
            if name in ("Q1", "Q2"):
                index = int(name[1]) - 1
                self._set_heater(index, _clip(_number(argument), 0.0, 100.0))
                return [f"{self._q[index]:.3f}"]
            if name in ("R1", "R2"):
                return [f"{self._q[int(name[1]) - 1]:.3f}"]
            if name in ("P1", "P2"):
                self._p[int(name[1]) - 1] = _clip(_number(argument), 0.0, 255.0)
                return [f"{self._p[int(name[1]) - 1]:.3f}"]
            if name == "LED":
                self._led = _clip(_number(argument), 0.0, 100.0)
                return [f"{self._led:.3f}"]
            if name == "SCAN":
                return [
                    self._temperature(1),
                    self._temperature(2),
                    f"{self._q[0]:.3f}",
                    f"{self._q[1]:.3f}",
                ]
            if name == "VER":
                return [f"TCLab Firmware {self.version} {self.board}"]
            if name == "X":
                self._all_off()
                return ["Stop"]
            if name == "WDOG" and self.watchdog_firmware:
                self.watchdog_period = int(_clip(_number(argument), 0.0, 3600.0))
                return [f"Watchdog {self.watchdog_period} s"]
            self._all_off()
            return [name]

    def _temperature(self, n: int) -> str:
        if self.sensor_disconnected:
            return "-50.000"
        return f"{self._heaters[n - 1].read().value:.3f}"

    def _set_heater(self, index: int, value: float) -> None:
        self._q[index] = value
        self._heaters[index].apply(value)

    def _all_off(self) -> None:
        self._set_heater(0, 0.0)
        self._set_heater(1, 0.0)


def _number(text: str) -> float:
    # As a microcontroller's string-to-float does: a missing or unreadable value is 0.
    try:
        value = float(text.split()[0]) if text else 0.0
    except ValueError:
        return 0.0
    return value if math.isfinite(value) else 0.0


def _clip(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


def main(argv: Sequence[str] | None = None) -> int:
    """Run an emulated kit until interrupted, printing its port.

    Parameters
    ----------
    argv : sequence of str, optional
        Command-line arguments (default ``sys.argv[1:]``): ``--speedup X``
        (thermal model X times faster than real time), ``--seed N``.

    Returns
    -------
    int
        Exit status (0).
    """
    parser = argparse.ArgumentParser(
        prog="python -m thermolab.rigs.tclab_emulator",
        description="Emulate a TCLab kit (firmware 2.0.1) on a pseudo-terminal.",
    )
    parser.add_argument("--speedup", type=float, default=1.0, help="thermal model speed-up")
    parser.add_argument("--seed", type=int, default=None, help="seed of the sensor noise")
    args = parser.parse_args(argv)
    with TCLabEmulator(clock=make_clock(args.speedup), seed=args.seed) as emulator:
        print(f"TCLab emulator on {emulator.port} (Ctrl-C to stop)", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            threading.Event().wait()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
