"""``thermolab.tclab.TCLab`` on a real lab: what course notebooks rely on, and clear refusals.

The lab is the session's ``thermolab serve`` (conftest): a kit's twin
(``sim:tclab``, one heater), the kit's two-heater twin (``sim:kit``) and the
paper's box (``sim``, volts) at 20x.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from typing import Any

import pytest
import tclab

from thermolab.client import Lab, LabRequestError, TurnEndedError
from thermolab.tclab import (
    AlreadyConnectedError,
    Historian,
    NotAKitError,
    NotOnThisRigError,
    PortError,
    SecondHeaterError,
    TCLab,
    clock,
    diagnose,
    labtime,
)

from .conftest import SPEEDUP, ServedLab, free_port


@pytest.fixture(autouse=True)
def _lab_time_restored() -> Iterator[None]:
    yield
    labtime.hold(1, None)
    labtime.set_rate(1)
    tclab.labtime.set_rate(1)


def _teacher(served_lab: ServedLab, path: str) -> dict[str, Any]:
    with contextlib.closing(served_lab.cookie_client("tina")) as teacher:
        answer: dict[str, Any] = teacher.get(path).json()
        return answer


def test_what_a_lab_rig_is_not_is_refused_clearly(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ana")
    with pytest.raises(PortError, match=r"TCLab\(port='nonsense'\): a lab rig has no serial port"):
        TCLab(port="nonsense", url=served_lab.url, token=token)
    assert issubclass(PortError, RuntimeError)  # what tclab raises for an unknown port
    nowhere = f"http://127.0.0.1:{free_port()}"
    with pytest.raises(LabRequestError, match=rf"^cannot reach the lab at {nowhere} "):
        TCLab(url=nowhere, token=token)
    # The paper's box: volts in, volts out. T1 would read volts as °C: refused, naming what it has.
    with pytest.raises(NotAKitError) as box:
        TCLab(url=served_lab.url, token=token, rig="box")
    message = str(box.value)
    assert (
        "rig 'box' (The paper's box) has one input (from -10 to 10 V) and one output (in V)"
        in message
    )
    assert "TCLab needs a heater in % and a temperature sensor in °C" in message
    assert _teacher(served_lab, "/api/rigs/box")["access"]["controller"] is None  # no turn


def test_the_kits_interface_on_one_heater(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ana")
    with TCLab(url=served_lab.url, token=token, rig="kit") as lab:
        assert lab.speedup == SPEEDUP
        assert labtime.get_rate() == SPEEDUP
        with pytest.raises(AlreadyConnectedError, match="already has an open TCLab on rig 'kit'"):
            TCLab(url=served_lab.url, token=token, rig="kit")
        # Q1(): read from the rig now, not a value kept by the client.
        assert lab.Q1(-10) == 0.0
        assert lab.Q1(120) == 100.0
        assert lab.Q1(0.5) == 0.5
        with Lab(served_lab.url, token) as raw:
            raw.request("PUT", "/api/rigs/kit/input", json={"u": 33.0})
        assert lab.Q1() == 33.0
        assert lab.U1 == 33.0
        assert isinstance(lab.T1, float)
        assert -10 < lab.T1 < 110
        # P1 below the kit's 200 scales the heater the rig receives, as the kit's PWM limit does.
        assert lab.P1 == 200.0
        lab.P1 = 100
        assert lab.Q1(80) == 80.0
        assert _teacher(served_lab, "/api/rigs/kit/reading")["u"] == 40.0
        assert lab.Q1() == 80.0
        assert lab.scan()[2] == 80.0
        with pytest.raises(NotOnThisRigError, match=r"full heater is the kit's P1 = 200"):
            lab.P1 = 300
        lab.P1 = 200
        for name, use in (
            ("Q2", lambda: lab.Q2(10)),
            ("T2", lambda: lab.T2),
            ("U2", lambda: lab.U2),
            ("P2", lambda: lab.P2),
        ):
            with pytest.raises(SecondHeaterError) as missing:
                use()
            assert "rig 'kit' (TCLab kit's twin) has one input (from 0 to 100 %)" in str(
                missing.value
            )
            assert f"so {name} does not exist there" in str(missing.value)
        _t1, t2, q1, q2 = lab.scan()
        assert math.isnan(t2)
        assert math.isnan(q2)
        assert q1 == 80.0
    assert _teacher(served_lab, "/api/rigs/kit/reading")["u"] == 0.0


def test_the_kits_second_heater_and_sensor_on_a_two_heater_rig(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ana")
    with TCLab(url=served_lab.url, token=token, rig="dual") as lab:
        assert lab.heaters == 2
        start = lab.T2
        assert 10.0 < start < 40.0
        assert lab.Q2(150) == 100.0  # clipped, as the kit clips
        assert lab.Q2() == 100.0  # read back from the rig
        assert lab.U2 == 100.0
        assert _teacher(served_lab, "/api/rigs/dual/reading")["channels"]["q2"] == 100.0
        # P2 below the kit's 100 scales heater 2, as the kit's PWM limit does.
        assert lab.P2 == 100.0
        lab.P2 = 50
        assert _teacher(served_lab, "/api/rigs/dual/reading")["channels"]["q2"] == 50.0
        assert lab.Q2() == 100.0
        with pytest.raises(NotOnThisRigError, match=r"full heater 2 is the kit's P2 = 100"):
            lab.P2 = 200
        lab.P2 = 100
        lab.U2 = 100
        deadline = labtime.time() + 120.0  # two lab minutes: 6 s at 20x
        while start + 2.0 > lab.T2:
            assert labtime.time() < deadline, "sensor 2 did not warm under heater 2"
            labtime.sleep(2.0)
        t1, t2, q1, q2 = lab.scan()
        assert (q1, q2) == (0.0, 100.0)
        assert t2 > t1  # heater 2 warms sensor 2 more than sensor 1
    reading = _teacher(served_lab, "/api/rigs/dual/reading")
    assert reading["channels"]["q2"] == 0.0  # close() and the release put heater 2 off


def _record(module: Any, lab: Any) -> Historian:
    h = module.Historian(lab.sources)
    for t in module.clock(10):
        lab.Q1(100 if t < 5 else 0)
        h.update(t)
    return h  # type: ignore[no-any-return]


def test_a_script_gives_the_same_shape_of_record_on_the_lab_as_on_tclabs_model(
    served_lab: ServedLab,
) -> None:
    # tclab's model at 5x (a step is 200 ms); the lab's twin at 20x, whose late steps are
    # taken at once on the twin's time, never skipped. tclab's own clock is real time: on a
    # busy machine it skips a step it woke too late for (a CI run logged 10 rows, t = 4.32
    # then 5.17) or takes two steps within a second of each other (another logged two
    # times that round to 3 s), so its record is checked for its shape: times that rise,
    # within the 10 s, most of them there.
    model = tclab.setup(connected=False, speedup=5)
    with model() as kit:
        theirs = _record(tclab, kit)
    _, token = served_lab.token("ben")
    with TCLab(url=served_lab.url, token=token, rig="kit") as lab:
        mine = _record(__import__("thermolab.tclab", fromlist=["clock"]), lab)
    assert mine.columns == theirs.columns == ["Time", "T1", "T2", "Q1", "Q2"]
    assert len(mine.log) == 11
    assert theirs.t == sorted(set(theirs.t))
    assert {round(t) for t in theirs.t} <= set(range(11))
    assert len(theirs.t) >= 8
    assert mine.t[0] == 0.0
    assert all(round(t) >= k for k, t in enumerate(mine.t))
    assert mine.t == sorted(set(mine.t))
    assert [type(v) for v in mine.log[0]] == [float] * 5
    assert [r[3] for r in mine.log] == [100.0 if t < 5 else 0.0 for t in mine.t]
    assert [float(r[3]) for r in theirs.log] == [100.0 if t < 5 else 0.0 for t in theirs.t]
    assert all(math.isnan(r[2]) and math.isnan(r[4]) for r in mine.log)  # one heater here


def test_a_turn_ended_from_outside_raises_naming_why(served_lab: ServedLab) -> None:
    _, token = served_lab.token("carl")
    lab = TCLab(url=served_lab.url, token=token, rig="kit")
    try:
        lab.Q1(70)
        with contextlib.closing(served_lab.cookie_client("tina")) as teacher:
            assert teacher.post("/api/rigs/kit/control/kick").status_code == 200
        assert _teacher(served_lab, "/api/rigs/kit/reading")["u"] == 0.0  # safe at once

        def go_on() -> None:
            for _ in clock(30):
                lab.Q1(70)

        with pytest.raises(TurnEndedError, match=r"the turn at rig 'kit' ended: .+ safe input"):
            go_on()
    finally:
        lab.close()
    assert labtime.held_by is None


def test_diagnose_checks_the_lab_the_rig_and_its_heater(
    served_lab: ServedLab, capsys: pytest.CaptureFixture[str]
) -> None:
    _, token = served_lab.token("ana")
    assert diagnose(url=served_lab.url, token=token, rig="kit", heat=60.0) is True
    report = capsys.readouterr().out
    assert "rig 'kit' (sim): input 0–100 %, output in degC" in report
    assert "We wrote Q1 = 0.5 % and read back Q1 = 0.5 %" in report
    assert "T1 reads per second" in report
    assert report.rstrip().endswith("Diagnostics complete")
    assert _teacher(served_lab, "/api/rigs/kit/reading")["u"] == 0.0


class _FakeLab:
    """What a turn's heartbeat thread asks of the lab, answered from a script."""

    def __init__(self) -> None:
        self.requests: list[str] = []

    def request(self, method: str, path: str, **kwargs: object) -> dict[str, Any]:
        self.requests.append(f"{method} {path}")
        return {}


def test_a_turn_is_extended_while_nobody_waits_and_says_when_someone_queues(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from thermolab.client import Turn

    fake = _FakeLab()
    rig = {"id": "kit", "limits": {"clientTimeout": 3600.0}}
    turn = Turn(fake, rig)  # type: ignore[arg-type]
    try:
        turn._watch_queue({"queueSize": 0, "timeLeft": 50.0, "canExtend": True})
        assert fake.requests == ["POST /api/rigs/kit/control/more-time"]
        turn._watch_queue({"queueSize": 0, "timeLeft": 150.0, "canExtend": False})
        for _ in range(2):  # said once, not at every heartbeat
            turn._watch_queue({"queueSize": 2, "timeLeft": 42.0, "canExtend": False})
        assert len(fake.requests) == 1
        said = capsys.readouterr().err
        assert said.count("waiting") == 1
        assert "rig 'kit': 2 waiting in the queue; this script's turn ends in 42 s" in said
        turn.lost = "a teacher ended the turn"
        with pytest.raises(TurnEndedError, match="ended: a teacher ended the turn"):
            turn.check()
    finally:
        turn._released.set()


def test_closing_gives_lab_time_back_at_the_notebooks_pace(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ben")
    labtime.set_rate(3)
    with TCLab(url=served_lab.url, token=token, rig="kit"):
        assert labtime.get_rate() == SPEEDUP
        assert labtime.held_by == f"rig 'kit' of the lab at {served_lab.url} runs at 20x"
    assert labtime.held_by is None
    assert labtime.get_rate() == 3.0
