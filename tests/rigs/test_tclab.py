"""The TCLab driver against the firmware emulator: protocol, detection, faults, safety."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
import threading
import time
import tty
from collections.abc import Callable, Iterator

import pytest

from thermolab.errors import (
    InvalidParameterError,
    RigError,
    RigFaultError,
    RigStateError,
    RigTimeoutError,
)
from thermolab.rigs.base import RigState
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab import TCLabRig, TCLabVersion, find_tclab
from thermolab.rigs.tclab_emulator import TCLabEmulator

TIMEOUT = 2.0  # seconds per exchange in these tests (0.2 s failed on a loaded CI)


class _OtherDevice:
    """A serial device that is not a TCLab: answers 'OK' to every line."""

    def __init__(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.port = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.02)
            if ready:
                try:
                    data = os.read(self._master, 1024)
                except OSError:
                    return
                for _ in range(data.count(b"\r")):
                    os.write(self._master, b"OK\r\n")

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        os.close(self._master)
        os.close(self._slave)


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


@pytest.fixture
def emulator(clock: VirtualClock) -> Iterator[TCLabEmulator]:
    with TCLabEmulator(clock=clock, seed=0, realism=False) as emu:
        yield emu


@pytest.fixture
def open_driver(emulator: TCLabEmulator, clock: VirtualClock) -> Iterator[Callable[..., TCLabRig]]:
    opened: list[TCLabRig] = []

    def make(**options: object) -> TCLabRig:
        settings: dict[str, object] = {
            "clock": clock,
            "reset_wait": 0.0,
            "timeout": TIMEOUT,
            "watchdog": None,
        }
        settings.update(options)
        rig = TCLabRig(emulator.port, **settings)  # type: ignore[arg-type]
        opened.append(rig)
        return rig

    yield make
    for rig in opened:
        rig.close()


def test_connect_checks_firmware_and_switches_heaters_off(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    assert rig.version == TCLabVersion(2, 0, 1, "Arduino Uno")
    assert emulator.commands[:2] == ["VER", "X"]
    info = rig.describe()
    assert (info.input_min, info.input_max, info.input_unit) == (0.0, 100.0, "%")
    assert (info.output_unit, info.output_limit, info.kind) == ("degC", 90.0, "tclab")


def test_apply_and_read_speak_the_protocol(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], clock: VirtualClock
) -> None:
    rig = open_driver()
    rig.power_on()
    assert rig.apply(42.12345) == 42.123
    assert emulator.commands[-1] == "Q1 42.123"
    assert emulator.heater(1) == 42.123
    assert emulator.heater(2) == 0.0
    clock.advance(300.0)
    reading = rig.read()
    assert emulator.commands[-2:] == ["T1", "T2"]  # sensor 2 is read with sensor 1
    assert reading.t == 300.0
    assert reading.value == pytest.approx(emulator.temperature(1), abs=5e-4)
    assert reading.value > 30.0


def test_heater_2_is_driven_and_sensor_2_read_as_the_kits_further_channels(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], clock: VirtualClock
) -> None:
    rig = open_driver()
    info = rig.describe()
    assert [c.name for c in info.further_inputs] == ["q2"]
    assert [(c.name, c.unit, c.limit) for c in info.further_outputs] == [("t2", "degC", 90.0)]
    with pytest.raises(RigStateError, match="call power_on"):
        rig.set_channel("q2", 50.0)  # an idle kit heats nothing
    assert emulator.heater(2) == 0.0
    rig.power_on()
    assert rig.set_channel("q2", 60.12345) == 60.123
    assert emulator.commands[-1] == "Q2 60.123"
    assert (emulator.heater(1), emulator.heater(2)) == (0.0, 60.123)
    assert rig.level("q2") == 60.123
    clock.advance(300.0)
    reading = rig.read()
    assert reading.further["t2"] == pytest.approx(emulator.temperature(2), abs=5e-4)
    assert reading.further["t2"] > 30.0 > reading.value  # heater 2 heats sensor 2, not 1
    with pytest.raises(InvalidParameterError, match="takes 0-100 %"):
        rig.set_channel("q2", 120.0)
    with pytest.raises(InvalidParameterError, match="no input 'fan'"):
        rig.set_channel("fan", 10.0)
    rig.power_off()
    assert emulator.heater(2) == 0.0
    assert rig.level("q2") == 0.0


def test_heater_2_goes_off_on_a_fault_and_on_close(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], clock: VirtualClock
) -> None:
    rig = open_driver()
    rig.power_on()
    rig.set_channel("q2", 80.0)
    emulator.sensor_disconnected = True
    with pytest.raises(RigFaultError):
        rig.read()
    assert emulator.heater(2) == 0.0
    assert rig.level("q2") == 0.0
    emulator.sensor_disconnected = False
    rig.clear_fault()
    rig.power_on()
    rig.set_channel("q2", 80.0)
    rig.close()
    assert emulator.heater(2) == 0.0


def test_sensor_2_over_temperature_cuts_both_heaters(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], clock: VirtualClock
) -> None:
    rig = open_driver(max_temperature=30.0)
    rig.power_on()
    rig.apply(5.0)
    rig.set_channel("q2", 100.0)
    clock.advance(300.0)
    with pytest.raises(RigFaultError, match=r"output t2 .* exceeds the limit of 30 degC"):
        rig.read()
    assert (emulator.heater(1), emulator.heater(2)) == (0.0, 0.0)
    assert rig.state is RigState.FAULTED


def test_late_replies_are_not_taken_for_the_next_answer(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], wait_until: Callable[..., bool]
) -> None:
    # Which replies come late is decided by the emulator, not by timing, so the
    # timeout can be generous: the exchanges that must succeed do so on a
    # loaded machine, and the held ones fail whatever its length.
    rig = open_driver(timeout=2.0)
    rig.power_on()
    rig.apply(20.0)
    emulator.hold_replies = True  # the kit stalls: the driver times out...
    with pytest.raises(RigTimeoutError):
        rig.read()
    # ... and switches the heaters off without waiting (its resync timed out too).
    assert wait_until(lambda: emulator.commands[-3:] == ["Q1 0", "Q2 0", "X"], timeout=30.0)
    assert emulator.heater(1) == 0.0
    # The kit catches up: its late '20.000', 'SYNC1', 'Stop'... lines now arrive
    # in front of the answer to whatever the driver asks next.
    emulator.hold_replies = False
    rig.clear_fault()
    rig.power_on()
    assert rig.apply(5.0) == 5.0
    assert rig.read().value == pytest.approx(emulator.temperature(1), abs=5e-4)
    assert any(c.startswith("SYNC") for c in emulator.commands)


def test_auto_detect_finds_the_one_tclab_among_several_ports(emulator: TCLabEmulator) -> None:
    other = _OtherDevice()
    with TCLabEmulator(seed=1) as silent, TCLabEmulator(seed=2) as noisy:
        silent.silent = True
        noisy.garbage = True
        candidates = [silent.port, other.port, "/dev/does-not-exist", noisy.port, emulator.port]
        try:
            start = time.monotonic()
            port, version = find_tclab(candidates, timeout=TIMEOUT, reset_wait=0.0)
            assert port == emulator.port
            assert version.text == "2.0.1"
            assert time.monotonic() - start < 10 * TIMEOUT  # probed in parallel
            with TCLabRig(
                None, candidates=candidates, timeout=TIMEOUT, reset_wait=0.0, watchdog=None
            ) as rig:
                assert rig.port == emulator.port
            with pytest.raises(RigError, match="no TCLab found") as info:
                find_tclab(candidates[:4], timeout=TIMEOUT, reset_wait=0.0)
            message = str(info.value)
            assert "no answer" in message
            assert "answered 'OK'" in message
            assert "does-not-exist" in message
        finally:
            other.close()


@pytest.mark.parametrize("version", ["1.4.3", "3.0.0"])
def test_unsupported_firmware_is_refused(version: str) -> None:
    with (
        TCLabEmulator(version=version) as emulator,
        pytest.raises(RigError, match=rf"firmware {version} .* not supported"),
    ):
        TCLabRig(emulator.port, reset_wait=0.0, timeout=TIMEOUT, watchdog=None)


def test_a_device_that_is_not_a_tclab_is_refused() -> None:
    other = _OtherDevice()
    try:
        with pytest.raises(RigError, match="is not a TCLab: it answered 'OK'"):
            TCLabRig(other.port, reset_wait=0.0, timeout=TIMEOUT, watchdog=None)
    finally:
        other.close()


def test_a_missing_port_is_a_clear_error() -> None:
    with pytest.raises(RigError, match="cannot open serial port '/dev/does-not-exist'"):
        TCLabRig("/dev/does-not-exist", reset_wait=0.0, timeout=TIMEOUT)


def test_a_silent_kit_at_connection_times_out() -> None:
    with TCLabEmulator() as emulator:
        emulator.silent = True
        start = time.monotonic()
        with pytest.raises(RigTimeoutError, match="did not answer 'VER'"):
            TCLabRig(emulator.port, reset_wait=0.0, timeout=TIMEOUT)
        assert time.monotonic() - start < 5 * TIMEOUT
    # The port was released: a second driver could open it (exclusive lock gone).


def test_a_kit_that_stops_answering_times_out_and_is_made_safe(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    rig.power_on()
    rig.apply(80.0)
    emulator.silent = True  # still obeys, never answers
    start = time.monotonic()
    with pytest.raises(RigTimeoutError, match=rf"did not answer 'T1' within {TIMEOUT:g} s"):
        rig.read()
    assert time.monotonic() - start < 5 * TIMEOUT
    assert rig.state is RigState.FAULTED
    assert emulator.heater(1) == 0.0
    assert emulator.heater(2) == 0.0


def test_garbage_is_a_fault_and_the_heaters_go_off(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    rig.power_on()
    rig.apply(60.0)
    emulator.garbage = True
    with pytest.raises(RigFaultError, match="garbage"):
        rig.read()
    assert rig.state is RigState.FAULTED
    assert emulator.heater(1) == 0.0


def test_an_ascii_but_wrong_answer_is_a_fault(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    rig.power_on()
    emulator.garbage = "hot"
    with pytest.raises(RigFaultError, match="answered 'hot' to 'T1', not a number"):
        rig.read()
    emulator.garbage = False
    rig.clear_fault()
    rig.power_on()
    emulator.garbage = "12.000"  # a number, but not the echo of what was sent
    with pytest.raises(RigFaultError, match=r"echoed 12\.0 for heater 1 set to 50\.000"):
        rig.apply(50.0)


def test_unplugging_is_a_fault_not_a_hang(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    rig.power_on()
    rig.apply(30.0)
    emulator.vanish()
    start = time.monotonic()
    with pytest.raises(RigFaultError, match="gone"):
        rig.read()
    assert time.monotonic() - start < 5 * TIMEOUT
    assert rig.state is RigState.FAULTED
    rig.close()
    assert rig.state is RigState.CLOSED


def test_over_temperature_cuts_the_heaters(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig], clock: VirtualClock
) -> None:
    rig = open_driver(max_temperature=30.0)
    rig.power_on()
    rig.apply(100.0)
    clock.advance(20.0)
    assert rig.read().value < 30.0
    clock.advance(280.0)
    with pytest.raises(RigFaultError, match=r"exceeds the limit of 30 degC"):
        rig.read()
    assert emulator.heater(1) == 0.0
    with pytest.raises(RigFaultError):
        rig.clear_fault()  # still too hot
    clock.advance(3000.0)
    rig.clear_fault()
    assert rig.state is RigState.IDLE


def test_a_dead_sensor_is_a_fault(
    emulator: TCLabEmulator, open_driver: Callable[..., TCLabRig]
) -> None:
    rig = open_driver()
    rig.power_on()
    rig.apply(50.0)
    emulator.sensor_disconnected = True
    with pytest.raises(RigFaultError, match="disconnected or broken sensor"):
        rig.read()
    assert emulator.heater(1) == 0.0


def test_the_watchdog_switches_off_a_silent_host(
    emulator: TCLabEmulator,
    open_driver: Callable[..., TCLabRig],
    clock: VirtualClock,
    wait_until: Callable[..., bool],
) -> None:
    rig = open_driver(watchdog=5.0)
    rig.power_on()
    rig.apply(70.0)
    for _ in range(4):  # an active host keeps it alive
        clock.advance(4.0)
        rig.read()
    time.sleep(0.1)  # real time for the watchdog thread to look (simulated time stands still)
    assert rig.fault() is None
    clock.advance(6.0)  # the host falls silent
    assert wait_until(lambda: rig.fault() is not None)
    assert "watchdog" in (rig.fault() or "")
    assert emulator.heater(1) == 0.0
    assert rig.state is RigState.FAULTED


def test_the_watchdog_watches_heater_2_too(
    emulator: TCLabEmulator,
    open_driver: Callable[..., TCLabRig],
    clock: VirtualClock,
    wait_until: Callable[..., bool],
) -> None:
    rig = open_driver(watchdog=5.0)
    rig.power_on()
    rig.set_channel("q2", 70.0)  # heater 1 off: heater 2 alone is still heating
    clock.advance(6.0)  # the host falls silent
    assert wait_until(lambda: rig.fault() is not None)
    assert "watchdog" in (rig.fault() or "")
    assert emulator.heater(2) == 0.0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"timeout": 0.0}, "timeout"),
        ({"watchdog": -1.0}, "watchdog"),
        ({"reset_wait": -1.0}, "reset_wait"),
        ({"max_temperature": float("nan")}, "max_temperature"),
    ],
)
def test_bad_options_are_refused(options: dict[str, float], message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        TCLabRig("/dev/null", **options)  # type: ignore[arg-type]


# -- the process ends: heaters off --------------------------------------------------

_CHILD = textwrap.dedent(
    """
    import sys, time
    from thermolab.rigs.tclab import TCLabRig
    rig = TCLabRig(sys.argv[1], reset_wait=0.0, timeout=1.0, watchdog=None)
    rig.power_on()
    rig.apply(40.0)
    print("ready", flush=True)
    if sys.argv[2] == "exit":
        sys.exit(0)  # never closed: atexit must switch off
    if sys.argv[2] == "raise":
        raise RuntimeError("boom")
    time.sleep(30)
    """
)


@pytest.mark.parametrize(
    ("how", "signum"),
    [("wait", signal.SIGTERM), ("wait", signal.SIGINT), ("exit", None), ("raise", None)],
)
def test_the_heaters_go_off_when_the_process_ends(how: str, signum: int | None) -> None:
    with TCLabEmulator() as emulator:
        with subprocess.Popen(
            [sys.executable, "-c", _CHILD, emulator.port, how],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        ) as child:
            try:
                assert child.stdout is not None
                assert child.stdout.readline().strip() == "ready"
                if signum is not None:
                    assert emulator.heater(1) == 40.0
                    child.send_signal(signum)
                child.communicate(timeout=10)
            finally:
                if child.poll() is None:
                    child.kill()
                    child.communicate()
        assert emulator.heater(1) == 0.0
        assert emulator.heater(2) == 0.0
        if signum == signal.SIGTERM:
            assert child.returncode == 128 + signal.SIGTERM
