"""The firmware emulator answers the TCLab 2.0.1 protocol as NOTES.md §6 states it."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest
import serial

from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab import TCLabRig
from thermolab.rigs.tclab_emulator import TCLabEmulator


@pytest.fixture
def link() -> Iterator[tuple[TCLabEmulator, serial.Serial, VirtualClock]]:
    clock = VirtualClock()
    with (
        TCLabEmulator(clock=clock, seed=0, realism=False) as emulator,
        serial.Serial(emulator.port, 115200, timeout=1.0) as port,
    ):
        yield emulator, port, clock


def _ask(port: serial.Serial, raw: bytes, lines: int = 1) -> list[str]:
    port.write(raw)
    return [port.readline().decode("ascii") for _ in range(lines)]


def test_version(link: tuple[TCLabEmulator, serial.Serial, VirtualClock]) -> None:
    _, port, _ = link
    assert _ask(port, b"VER\r\n") == ["TCLab Firmware 2.0.1 Arduino Uno\r\n"]


def test_commands_are_case_insensitive_and_crlf_gives_one_reply(
    link: tuple[TCLabEmulator, serial.Serial, VirtualClock],
) -> None:
    emulator, port, _ = link
    assert _ask(port, b"q1 37.5\r\n") == ["37.500\r\n"]
    assert _ask(port, b"r1\n") == ["37.500\r\n"]  # LF alone ends a command too
    assert _ask(port, b"R1\r") == ["37.500\r\n"]
    port.timeout = 0.1
    assert port.readline() == b""  # no reply to the empty command of a CRLF pair
    assert emulator.heater(1) == 37.5


def test_heater_values_are_clipped_and_echoed(
    link: tuple[TCLabEmulator, serial.Serial, VirtualClock],
) -> None:
    emulator, port, _ = link
    assert _ask(port, b"Q1 150\r\n") == ["100.000\r\n"]
    assert _ask(port, b"Q2 -3\r\n") == ["0.000\r\n"]
    assert _ask(port, b"P1 300\r\n") == ["255.000\r\n"]
    assert emulator.heater(1) == 100.0
    assert emulator.power_limit(1) == 255.0


def test_temperatures_follow_the_heater(
    link: tuple[TCLabEmulator, serial.Serial, VirtualClock],
) -> None:
    emulator, port, clock = link
    assert _ask(port, b"T1\r\n") == ["21.000\r\n"]
    _ask(port, b"Q1 50\r\n")
    clock.advance(600.0)
    t1 = float(_ask(port, b"T1\r\n")[0])
    t2 = float(_ask(port, b"T2\r\n")[0])
    assert t1 == pytest.approx(emulator.temperature(1), abs=5e-4)
    assert 40.0 < t1 < 51.0
    assert t2 == 21.0


def test_scan_gives_four_lines(link: tuple[TCLabEmulator, serial.Serial, VirtualClock]) -> None:
    _, port, _ = link
    _ask(port, b"Q2 12.25\r\n")
    assert _ask(port, b"SCAN\r\n", lines=4) == [
        "21.000\r\n",
        "21.000\r\n",
        "0.000\r\n",
        "12.250\r\n",
    ]


def test_x_and_unknown_commands_switch_both_heaters_off(
    link: tuple[TCLabEmulator, serial.Serial, VirtualClock],
) -> None:
    emulator, port, _ = link
    _ask(port, b"Q1 10\r\nQ2 20\r\n", lines=2)
    assert _ask(port, b"X\r\n") == ["Stop\r\n"]
    assert (emulator.heater(1), emulator.heater(2)) == (0.0, 0.0)
    _ask(port, b"Q1 10\r\n")
    assert _ask(port, b"hello 3\r\n") == ["HELLO\r\n"]
    assert emulator.heater(1) == 0.0
    assert emulator.commands[-1] == "HELLO 3"


def test_misbehaviour_switches(link: tuple[TCLabEmulator, serial.Serial, VirtualClock]) -> None:
    emulator, port, _ = link
    port.timeout = 0.2
    emulator.garbage = True
    port.write(b"T1\r\n")
    reply = port.readline()
    assert reply.endswith(b"\r\n")
    assert not reply.isascii()
    emulator.garbage = False
    emulator.silent = True
    port.write(b"Q1 5\r\n")
    assert port.readline() == b""
    assert emulator.heater(1) == 5.0  # obeyed, not answered
    emulator.vanish()
    assert emulator.vanished

    def ask_again() -> None:
        port.write(b"T1\r\n")
        port.readline()

    with pytest.raises(serial.SerialException):
        ask_again()


def test_the_emulator_runs_as_a_program_for_rehearsal() -> None:
    with subprocess.Popen(
        [sys.executable, "-m", "thermolab.rigs.tclab_emulator", "--speedup", "50", "--seed", "1"],
        stdout=subprocess.PIPE,
        text=True,
    ) as program:
        try:
            assert program.stdout is not None
            banner = program.stdout.readline()
            assert banner.startswith("TCLab emulator on /dev/")
            port = banner.split()[3]
            with TCLabRig(port, reset_wait=0.0, timeout=1.0, watchdog=None) as rig:
                assert rig.version.text == "2.0.1"
                assert 15.0 < rig.read().value < 30.0
            program.send_signal(signal.SIGINT)
            program.communicate(timeout=120)  # loaded CI machines took over 10 s, then over 30 s
            assert program.returncode == 0
        finally:
            if program.poll() is None:
                program.kill()
                program.communicate()
