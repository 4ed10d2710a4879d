"""Finding and opening a TCLab kit's serial port.

:func:`find_tclab` asks ``VER`` on every serial port (in parallel, so the
boards' reset waits overlap) and returns the first that answers as a TCLab,
with its :class:`TCLabVersion`. :func:`open_port` opens a port as the driver
(:class:`~thermolab.rigs.tclab.TCLabRig`) talks to a kit: exclusive, with one
timeout for reads and writes. :data:`PORT_ERRORS` are what a port raises when
its device goes away (unplugged).
"""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import serial
import serial.tools.list_ports

from thermolab.errors import RigError

__all__ = ["PORT_ERRORS", "TCLabVersion", "find_tclab", "open_port"]

try:  # POSIX: pyserial lets termios errors (EIO from an unplugged device) escape
    import termios

    PORT_ERRORS: tuple[type[BaseException], ...] = (
        serial.SerialException,
        OSError,
        termios.error,
    )
except ImportError:  # pragma: no cover - Windows
    PORT_ERRORS = (serial.SerialException, OSError)

_VERSION_RE = re.compile(r"^TCLab Firmware (\d+)\.(\d+)\.(\d+)\s*(.*)$")


@dataclass(frozen=True, slots=True)
class TCLabVersion:
    """A kit's answer to ``VER``.

    Attributes
    ----------
    major, minor, patch : int
        Firmware version.
    board : str
        Board name (``"Arduino Uno"``, ``"Arduino Leonardo"``...).

    Examples
    --------
    >>> TCLabVersion.parse("TCLab Firmware 2.0.1 Arduino Uno")
    TCLabVersion(major=2, minor=0, patch=1, board='Arduino Uno')
    >>> TCLabVersion.parse("hello") is None
    True
    """

    major: int
    minor: int
    patch: int
    board: str

    @classmethod
    def parse(cls, reply: str) -> TCLabVersion | None:
        """Parse a ``VER`` reply; ``None`` if it is not a TCLab's."""
        match = _VERSION_RE.match(reply.strip())
        if match is None:
            return None
        major, minor, patch, board = match.groups()
        return cls(int(major), int(minor), int(patch), board)

    @property
    def text(self) -> str:
        """``"2.0.1"``."""
        return f"{self.major}.{self.minor}.{self.patch}"


def open_port(port: str, baudrate: float, timeout: float) -> serial.Serial:
    """Open ``port`` for one user, with ``timeout`` for reads and writes.

    Raises
    ------
    RigError
        If the port cannot be opened (missing, busy, no permission).
    """
    try:
        return serial.Serial(
            port, int(baudrate), timeout=timeout, write_timeout=timeout, exclusive=True
        )
    except (serial.SerialException, OSError, ValueError) as exc:
        raise RigError(f"cannot open serial port {port!r}: {exc}") from None


def _probe(port: str, baudrate: int, timeout: float, reset_wait: float) -> str:
    """Open ``port``, ask ``VER`` and return the reply line (``""`` if none)."""
    with open_port(port, baudrate, timeout) as link:
        time.sleep(reset_wait)  # a physical board reset, not simulated time
        link.reset_input_buffer()
        link.write(b"VER\r\n")
        return bytes(link.read_until(b"\n")).decode("ascii", errors="replace").strip()


def find_tclab(
    candidates: Sequence[str] | None = None,
    *,
    baudrate: int = 115200,
    timeout: float = 1.0,
    reset_wait: float = 2.0,
) -> tuple[str, TCLabVersion]:
    """Find a TCLab kit by asking every serial port ``VER``.

    Every candidate port is probed (in parallel, so the boards' reset waits
    overlap), not only ports with a known USB id: clones and other boards
    carry other ids.

    Parameters
    ----------
    candidates : sequence of str, optional
        Ports to probe, in order of preference; default: every serial port
        the operating system lists.
    baudrate : int
        Baud rate (115200 for firmware 2.x).
    timeout : float
        Seconds to wait for each reply.
    reset_wait : float
        Seconds to wait after opening a port (a board resets when its port
        opens, about 2 s).

    Returns
    -------
    tuple of (str, TCLabVersion)
        The first candidate that answered as a TCLab, and its version.

    Raises
    ------
    RigError
        If no port answered as a TCLab (the message says what each port did).
    """
    ports = (
        list(candidates)
        if candidates is not None
        else [info.device for info in serial.tools.list_ports.comports()]
    )
    if not ports:
        raise RigError("no TCLab found: there is no serial port on this machine")

    def attempt(port: str) -> str | Exception:
        try:
            return _probe(port, baudrate, timeout, reset_wait)
        except Exception as exc:  # a port that fails only rules itself out
            return exc

    with ThreadPoolExecutor(max_workers=min(len(ports), 16)) as pool:
        outcomes = list(pool.map(attempt, ports))
    reports = []
    for port, outcome in zip(ports, outcomes, strict=True):
        if isinstance(outcome, Exception):
            reports.append(f"{port} ({outcome})")
            continue
        version = TCLabVersion.parse(outcome)
        if version is not None:
            return port, version
        reports.append(f"{port} (" + (f"answered {outcome!r}" if outcome else "no answer") + ")")
    raise RigError("no TCLab found; probed " + "; ".join(reports))
