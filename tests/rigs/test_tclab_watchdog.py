"""The kit's own watchdog (issue #13 item 9): armed by the driver when the firmware has one."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from thermolab.errors import InvalidParameterError
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab import TCLabRig
from thermolab.rigs.tclab_emulator import FIRMWARE_WATCHDOG_DEFAULT, TCLabEmulator

SKETCH = Path(__file__).parents[2] / "firmware" / "tclab_watchdog" / "tclab_watchdog.ino"


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


def _kit(clock: VirtualClock, *, watchdog_firmware: bool) -> Iterator[TCLabEmulator]:
    with TCLabEmulator(
        clock=clock, seed=0, realism=False, watchdog_firmware=watchdog_firmware
    ) as kit:
        yield kit


@pytest.fixture
def sketch_kit(clock: VirtualClock) -> Iterator[TCLabEmulator]:
    yield from _kit(clock, watchdog_firmware=True)


@pytest.fixture
def stock_kit(clock: VirtualClock) -> Iterator[TCLabEmulator]:
    yield from _kit(clock, watchdog_firmware=False)


def _driver(kit: TCLabEmulator, clock: VirtualClock, **options: object) -> TCLabRig:
    # watchdog=None: no host-side guard, as after a kill -9 of the server.
    return TCLabRig(kit.port, clock=clock, reset_wait=0.0, timeout=0.5, watchdog=None, **options)  # type: ignore[arg-type]


def test_the_driver_arms_the_sketch_watchdog(
    sketch_kit: TCLabEmulator, clock: VirtualClock
) -> None:
    assert sketch_kit.watchdog_period == FIRMWARE_WATCHDOG_DEFAULT  # armed from power-on
    with _driver(sketch_kit, clock, firmware_watchdog=12) as rig:
        assert rig.firmware_watchdog == 12
        assert sketch_kit.watchdog_period == 12
        assert "WDOG 12" in sketch_kit.commands


def test_a_silent_host_gets_its_heater_switched_off_by_the_kit(
    sketch_kit: TCLabEmulator, clock: VirtualClock
) -> None:
    rig = _driver(sketch_kit, clock, firmware_watchdog=12)
    try:
        rig.power_on()
        rig.apply(60.0)
        clock.advance(11.0)
        rig.read()  # any command restarts the period
        clock.advance(11.0)
        assert sketch_kit.heater(1) == 60.0
        # The host dies (kill -9): nothing more is sent.
        clock.advance(12.0)
        assert sketch_kit.heater(1) == 0.0
        assert sketch_kit.watchdog_trips == 1
    finally:
        rig.close()


def test_stock_firmware_has_no_watchdog_and_the_heater_stays_on(
    stock_kit: TCLabEmulator, clock: VirtualClock
) -> None:
    rig = _driver(stock_kit, clock)
    try:
        assert rig.firmware_watchdog is None  # WDOG was echoed: unknown to the stock firmware
        assert "WDOG 15" in stock_kit.commands
        rig.power_on()
        rig.apply(60.0)
        clock.advance(3600.0)
        # What a kill -9 costs without the sketch: the heater stays on until the board resets.
        assert stock_kit.heater(1) == 60.0
    finally:
        rig.close()


def test_not_asking_keeps_the_power_on_default(
    sketch_kit: TCLabEmulator, clock: VirtualClock
) -> None:
    with _driver(sketch_kit, clock, firmware_watchdog=None) as rig:
        assert rig.firmware_watchdog is None
        assert not any(c.startswith("WDOG") for c in sketch_kit.commands)
        assert sketch_kit.watchdog_period == FIRMWARE_WATCHDOG_DEFAULT


@pytest.mark.parametrize("bad", [0, 3601, 2.5, -1])
def test_a_bad_firmware_watchdog_is_refused(stock_kit: TCLabEmulator, bad: object) -> None:
    with pytest.raises(InvalidParameterError, match="firmware_watchdog"):
        TCLabRig(stock_kit.port, reset_wait=0.0, firmware_watchdog=bad)  # type: ignore[arg-type]


def test_the_sketch_speaks_the_protocol() -> None:
    text = SKETCH.read_text(encoding="ascii")
    for command in ("T1", "T2", "Q1", "Q2", "R1", "R2", "P1", "P2", "LED", "SCAN", "VER", "WDOG"):
        assert f'"{command}"' in text, command
    assert "TCLab Firmware 2.0.1" in text
    assert "Watchdog" in text


_ARDUINO_AVR = Path("/usr/share/arduino/hardware/arduino/avr")


@pytest.mark.skipif(
    shutil.which("avr-g++") is None or not (_ARDUINO_AVR / "cores/arduino/Arduino.h").is_file(),
    reason="needs gcc-avr and the Arduino AVR core (Debian: apt install gcc-avr avr-libc "
    "arduino-core-avr)",
)
def test_the_sketch_compiles_for_an_uno(tmp_path: Path) -> None:
    # Compile only (no link, no upload): the sketch's functions are declared before use, so
    # the .ino is C++ once Arduino.h is included, as the Arduino builder does.
    result = subprocess.run(
        [
            "avr-g++",
            "-c",
            "-x",
            "c++",
            "-std=gnu++11",
            "-Os",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-mmcu=atmega328p",
            "-DF_CPU=16000000L",
            "-DARDUINO=10807",
            "-DARDUINO_AVR_UNO",
            "-DARDUINO_ARCH_AVR",
            f"-I{_ARDUINO_AVR}/cores/arduino",
            f"-I{_ARDUINO_AVR}/variants/standard",
            "-include",
            "Arduino.h",
            str(SKETCH),
            "-o",
            str(tmp_path / "tclab_watchdog.o"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
