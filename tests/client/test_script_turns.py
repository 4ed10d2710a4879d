"""A script's turn: extended while nobody waits, told why it ended, safe at once; its speed-up.

The lab is the session's ``thermolab serve`` (conftest); the script is
``thermolab.tclab.TCLab`` with a personal API token, as a course script runs.
These tests heat rig ``kit2``, so that ``kit`` starts cool in the others, and
rigs ``brief`` and ``brief2``, whose 12 s turns a script outlives only by
extensions. One teacher login serves them all: the lab limits password logins
per address.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator

import httpx
import pytest

from thermolab.client import TurnEndedError
from thermolab.tclab import SpeedupRefusedError, TCLab, clock, labtime, setup

from .conftest import BRIEF_TURN, SPEEDUP, ServedLab

RIG = "kit2"


@pytest.fixture(autouse=True)
def _lab_time_restored() -> Iterator[None]:
    yield
    labtime.hold(1, None)
    labtime.set_rate(1)


@pytest.fixture(scope="module")
def teacher(served_lab: ServedLab) -> Iterator[httpx.Client]:
    with contextlib.closing(served_lab.cookie_client("tina")) as client:
        yield client


def _rig(teacher: httpx.Client) -> dict[str, object]:
    answer: dict[str, object] = teacher.get(f"/api/rigs/{RIG}").json()
    return answer


def _heater(teacher: httpx.Client) -> float:
    return float(teacher.get(f"/api/rigs/{RIG}/reading").json()["u"])


def _read_until_refused(kit: TCLab, seconds: float) -> None:
    """Read T1 every 0.1 s until it raises (or ``seconds`` pass, which fails the test)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        assert kit.T1 > -50
        time.sleep(0.1)


def _script_heating(served_lab: ServedLab, teacher: httpx.Client, token: str) -> TCLab:
    kit = TCLab(url=served_lab.url, token=token, rig=RIG)
    kit.Q1(80)
    assert _heater(teacher) == 80.0
    return kit


def test_revoking_a_scripts_token_ends_its_turn_and_makes_the_rig_safe_at_once(
    served_lab: ServedLab, teacher: httpx.Client
) -> None:
    with contextlib.closing(served_lab.cookie_client("ana")) as ana:
        made = ana.post("/api/tokens", json={"name": "script"}).json()
        kit = _script_heating(served_lab, teacher, made["token"])
        try:
            assert ana.delete(f"/api/tokens/{made['id']}").status_code == 204
            # Safe before the lab answered the revocation: not at the 15 s client timeout.
            assert _heater(teacher) == 0.0
            access = _rig(teacher)["access"]
            assert isinstance(access, dict)
            assert access["controller"] is None  # the turn is over, not only the heater
            with pytest.raises(TurnEndedError, match="revoked"):
                kit.Q1(80)
        finally:
            kit.close()


def test_a_teacher_kicking_a_script_makes_the_rig_safe_at_once(
    served_lab: ServedLab, teacher: httpx.Client
) -> None:
    _, token = served_lab.token("ben")
    kit = _script_heating(served_lab, teacher, token)
    try:
        assert teacher.post(f"/api/rigs/{RIG}/control/kick").status_code == 200
        assert _heater(teacher) == 0.0  # safe before the lab answered the kick
        # The script's next command is refused, and the error names who ended the turn.
        with pytest.raises(TurnEndedError, match=r"ended: a teacher \(tina\) ended it\. The lab"):
            kit.Q1(80)
    finally:
        kit.close()


def test_a_script_only_reading_learns_from_its_heartbeat_who_ended_its_turn(
    served_lab: ServedLab, teacher: httpx.Client
) -> None:
    _, token = served_lab.token("ben")
    kit = _script_heating(served_lab, teacher, token)
    try:
        assert teacher.post(f"/api/rigs/{RIG}/control/kick").status_code == 200
        # Reading is open to watchers, so the script hears of the end at its next heartbeat
        # (a third of the client timeout); T1 then raises, naming why.
        with pytest.raises(TurnEndedError, match=r"ended: a teacher \(tina\) ended it\. The lab"):
            _read_until_refused(kit, seconds=60)
    finally:
        kit.close()


def test_setup_speedup_paces_the_twin_for_the_scripts_turn_and_then_gives_it_back(
    served_lab: ServedLab, teacher: httpx.Client
) -> None:
    _, token = served_lab.token("carl")
    TwinLab = setup(connected=False, speedup=5, twin=True)
    with TwinLab(url=served_lab.url, token=token, rig=RIG) as kit:
        assert kit.speedup == 5.0
        assert labtime.get_rate() == 5.0  # clock() and labtime follow the twin's pace
        assert _rig(teacher)["speedup"] == 5.0  # the lab runs its twin at it
    assert _rig(teacher)["speedup"] == SPEEDUP  # the teacher's again once the turn is over
    # One the twin does not allow is refused, naming the rig and its range, turn given back.
    TwinLab = setup(connected=False, speedup=100, twin=True)
    with pytest.raises(SpeedupRefusedError) as refused:
        TwinLab(url=served_lab.url, token=token, rig=RIG)
    assert "speedup=100" in str(refused.value)
    assert f"rig '{RIG}' (a twin) allows speed-ups from 1x to 20x" in str(refused.value)
    rig = _rig(teacher)
    assert isinstance(rig["access"], dict)
    assert rig["access"]["controller"] is None
    assert rig["speedup"] == SPEEDUP
    assert labtime.held_by is None


def test_a_20_minute_1_s_script_outlives_its_turns_limit_while_nobody_waits(
    served_lab: ServedLab, teacher: httpx.Client
) -> None:
    # Rig 'brief' gives 12 s turns; 20 lab minutes at the twin's 20x take 60 s or more.
    _, token = served_lab.token("ana")
    temperatures = []
    with TCLab(url=served_lab.url, token=token, rig="brief") as kit:
        started = time.monotonic()
        for t in clock(20 * 60, 1):
            kit.Q1(60 if t < 600 else 0)
            temperatures.append(kit.T1)
        took = time.monotonic() - started
        access = _rig_named(teacher, "brief")["access"]
        assert isinstance(access, dict)
        assert access["controller"] == "ana"  # still the script's turn at the last sample
    assert len(temperatures) == 20 * 60 + 1  # every second of the 20 minutes, none skipped
    assert took > BRIEF_TURN * 4  # the turn outlived its limit by the client's extensions


def test_once_someone_queues_a_script_is_told_its_time_left_then_why_its_turn_ended(
    served_lab: ServedLab, teacher: httpx.Client, capsys: pytest.CaptureFixture[str]
) -> None:
    _, token = served_lab.token("ben")
    kit = TCLab(url=served_lab.url, token=token, rig="brief2")
    try:
        with contextlib.closing(served_lab.cookie_client("carl")) as carl:
            # Carl queues before the script's first heartbeat (a third of the 15 s timeout).
            place = carl.post("/api/rigs/brief2/control").json()["access"]
            assert place["role"] == "queued"

            def heat_and_keep_carls_place() -> None:
                kit.Q1(60)
                carl.post("/api/rigs/brief2/heartbeat")

            with pytest.raises(
                TurnEndedError,
                match=r"ended: its time limit ran out \(a turn is extended only while nobody "
                r"waits for the rig\)\. The lab put the rig at its safe input",
            ):
                _repeat_for(heat_and_keep_carls_place, seconds=60)
            assert _rig_named(teacher, "brief2")["access"]["controller"] == "carl"  # type: ignore[index]
            carl.delete("/api/rigs/brief2/control")
    finally:
        kit.close()
    told = capsys.readouterr().err
    assert "rig 'brief2': 1 waiting in the queue; this script's turn ends in " in told
    assert "(no more extensions while someone waits)" in told


def _rig_named(teacher: httpx.Client, rig: str) -> dict[str, object]:
    answer: dict[str, object] = teacher.get(f"/api/rigs/{rig}").json()
    return answer


def _repeat_for(step: Callable[[], None], seconds: float) -> None:
    """Call ``step`` every 0.2 s until it raises (or ``seconds`` pass, which fails the test)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        step()
        time.sleep(0.2)
