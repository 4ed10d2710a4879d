"""``thermolab.tclab`` against the ``tclab`` package (1.0.0, a test dependency) as the oracle.

Offline: names and signatures, the record a script makes on ``TCLabModel``,
the model's physics and sensor, ``labtime``/``clock``/``setup``/``Historian``
as course notebooks use them. Time is virtual (``synced=False``) or fast.
"""

from __future__ import annotations

import inspect
import math
import random
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import tclab

import thermolab.tclab as ours
from thermolab.kit_physics import KitConstants, KitPhysics, sensor_reading
from thermolab.tclab import (
    Historian,
    LabTimeStoppedError,
    NotOnThisRigError,
    TCLab,
    TCLabModel,
    clock,
    labtime,
    setnow,
    setup,
)

PUBLIC = ["TCLab", "TCLabModel", "Historian", "Plotter", "Experiment", "runexperiment"]
PUBLIC += ["clock", "labtime", "setnow", "setup", "diagnose", "__version__"]


@pytest.fixture(autouse=True)
def _lab_time_restored() -> Iterator[None]:
    yield
    labtime.hold(1, None)
    labtime.start()
    labtime.set_rate(1)
    tclab.labtime.set_rate(1)


@pytest.fixture(autouse=True)
def _no_lab(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("THERMOLAB_URL", raising=False)


def _parameters(thing: Any) -> list[tuple[str, Any]]:
    # Positional parameters as tclab has them; keyword-only ones are our additions.
    signature = inspect.signature(thing)
    return [
        (p.name, p.default)
        for p in signature.parameters.values()
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name != "self"
    ]


@pytest.mark.parametrize("name", PUBLIC)
def test_every_public_name_of_tclab_is_here_with_its_signature(name: str) -> None:
    theirs, mine = getattr(tclab, name), getattr(ours, name)
    if callable(theirs) and not isinstance(theirs, type(tclab.labtime)):
        assert _parameters(mine) == _parameters(theirs), name
    assert ours.__version__ == tclab.__version__ == "1.0.0"


@pytest.mark.parametrize(
    ("cls", "members"),
    [
        ("TCLab", "T1 T2 Q1 Q2 U1 U2 P1 P2 LED scan close __enter__ __exit__"),
        ("TCLabModel", "T1 T2 Q1 Q2 U1 U2 P1 P2 LED scan close update quantize measurement"),
        ("Historian", "update at after to_csv get_sessions load_session new_session close"),
        ("Historian", "log timeindex timeslice"),
    ],
)
def test_the_classes_have_the_kits_members_with_their_signatures(cls: str, members: str) -> None:
    for member in members.split():
        theirs = getattr(getattr(tclab, cls), member)
        mine = getattr(getattr(ours, cls), member)
        assert isinstance(mine, property) == isinstance(theirs, property), member
        if callable(theirs):
            assert _parameters(mine) == _parameters(theirs), f"{cls}.{member}"
    for method in ("time", "sleep", "set_rate", "get_rate", "stop", "start", "reset"):
        assert _parameters(getattr(labtime, method)) == _parameters(
            getattr(tclab.labtime, method)
        ), method


def _step_script(module: Any, model: Any) -> tuple[list[str], list[tuple[Any, ...]]]:
    """A course notebook's step test, virtual time: Q1 at 100 % for 100 s, then off."""

    def step(t: float, lab: Any) -> None:
        lab.Q1(100 if t < 100 else 0)
        lab.Q2(50 if t >= 150 else 0)

    with module.Experiment(connected=False, plot=False, time=300, synced=False) as experiment:
        assert isinstance(experiment.lab, model)
        for t in experiment.clock():
            step(t, experiment.lab)
    h = experiment.historian
    return list(h.columns), list(h.log)


def test_the_same_script_gives_the_same_record_on_our_model_and_tclabs() -> None:
    random.seed(3)
    their_columns, theirs = _step_script(tclab, tclab.TCLabModel)
    our_columns, mine = _step_script(ours, TCLabModel)
    assert our_columns == their_columns == ["Time", "T1", "T2", "Q1", "Q2"]
    assert len(mine) == len(theirs) == 300
    assert [r[0] for r in mine] == [r[0] for r in theirs]
    assert [r[3:] for r in mine] == [r[3:] for r in theirs]
    assert {type(v) for r in mine for v in r[:3]} == {float}
    # The same physics: within the sensors' noise (0.043 °C) and count (0.32 °C) of each other.
    for column in (1, 2):
        a = np.array([r[column] for r in mine])
        b = np.array([r[column] for r in theirs])
        assert np.max(np.abs(a - b)) < 1.0, column
        assert abs(float(np.mean(a - b))) < 0.2, column
    peak = max(r[1] for r in mine)
    assert 45.0 < peak < 60.0  # 100 % for 100 s: the kit's first minutes


def test_the_model_has_two_heaters_that_exchange_heat() -> None:
    kit = KitPhysics()
    kit.advance(300.0, q1=0.0, q2=100.0, p1=200.0, p2=100.0)
    assert kit.temperatures is not None
    th1, th2, ts1, ts2 = kit.temperatures
    assert th2 > th1 > 21.5
    assert ts2 > ts1 > 21.0
    # Exact steps: one step of 300 s is 1500 steps of 0.2 s.
    fine = KitPhysics()
    for _ in range(1500):
        fine.advance(0.2, q1=0.0, q2=100.0, p1=200.0, p2=100.0)
    np.testing.assert_allclose(fine.temperatures, kit.temperatures, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="at least 0 s"):
        kit.advance(-1.0, q1=0, q2=0, p1=200, p2=100)
    with pytest.raises(ValueError, match="tau_sensor must be positive"):
        KitConstants(tau_sensor=0.0)


def test_the_sensor_is_quantised_and_noisy_like_the_kits() -> None:
    model = TCLabModel(seed=7)
    reference = tclab.TCLabModel()
    for t in (-100.0, 20.0, 21.7, 300.0):
        assert model.quantize(t) == pytest.approx(reference.quantize(t), abs=1e-9)
    counts = {round(v / 0.3223, 6) for v in (model.quantize(20 + k / 10) for k in range(50))}
    assert all(c == int(c) for c in counts)  # whole counts of the converter
    readings = [model.measurement(30.0) for _ in range(2000)]
    assert all(abs(r - 30.0) <= 1.0 for r in readings)
    assert len(set(readings)) >= 2  # the noise crosses counts
    assert TCLabModel(seed=7).measurement(30.0) == TCLabModel(seed=7).measurement(30.0)
    quiet = KitConstants(noise=0.0)
    assert sensor_reading(40.0, quiet, random.Random(1)) == sensor_reading(40.0, quiet)


def test_the_models_heaters_limits_and_led_clip_as_the_kits() -> None:
    lab = TCLabModel(synced=False)
    for q in (lab.Q1, lab.Q2):
        assert [q(-10), q(50), q(0.5), q(120)] == [0.0, 50.0, 0.5, 100.0]
    lab.U2 = 30
    assert lab.U2 == 30.0
    assert (lab.P1, lab.P2) == (200.0, 100.0)
    lab.P1 = 300
    assert lab.P1 == 255.0
    assert lab.LED(150) == 100.0
    t1, t2, q1, q2 = lab.scan()
    assert (q1, q2) == (100.0, 30.0)
    assert 20.0 < t1 < 22.0
    assert 20.0 < t2 < 22.0
    lab.update(600.0)
    assert lab.T1 > 60.0 > lab.T2 > 25.0
    with pytest.raises(ValueError, match="must be a number"):
        lab.Q1(math.nan)
    lab.close()
    assert (lab.Q1(), lab.Q2()) == (0.0, 0.0)


def test_setup_switches_between_the_model_and_the_lab(monkeypatch: pytest.MonkeyPatch) -> None:
    assert setup(connected=False, speedup=10) is TCLabModel
    assert labtime.get_rate() == 10
    assert setup(connected=True) is TCLab
    assert labtime.get_rate() == 1
    monkeypatch.setenv("THERMOLAB_URL", "http://127.0.0.1:9")
    twin = setup(connected=False, speedup=5)
    assert issubclass(twin, TCLab)
    assert twin is not TCLab
    assert setup(connected=False, speedup=5, twin=False) is TCLabModel
    for bad in ({"connected": True, "speedup": 2}, {"connected": False, "speedup": 0}):
        with pytest.raises(ValueError, match="speedup"):
            setup(**bad)
    with pytest.raises(NotOnThisRigError, match="synced=False"):
        ours.Experiment(connected=False, synced=False)
    with pytest.raises(ValueError, match="real time"):
        ours.Experiment(connected=True, speedup=10)


def test_labtime_has_the_kits_names() -> None:
    labtime.set_rate(4)
    assert labtime.get_rate() == labtime.rate == 4.0
    labtime.set_rate()
    assert labtime.get_rate() == 1.0
    setnow(10)
    assert 10.0 <= labtime.time() < 10.5
    labtime.stop()
    with pytest.raises(RuntimeWarning, match="stopped") as stopped:
        labtime.sleep(1)
    assert isinstance(stopped.value, LabTimeStoppedError)
    labtime.start()
    labtime.hold(20, "rig 'kit' of the lab at http://lab runs at 20x")
    with pytest.raises(ValueError, match=r"runs at 20x because rig 'kit'.* cannot change it to 5x"):
        labtime.set_rate(5)
    labtime.set_rate(20)  # the same rate is no change


def test_a_lab_twins_clock_takes_every_step_late_rather_than_skip(
    capsys: pytest.CaptureFixture[str],
) -> None:
    labtime.hold(100, "rig 'kit' of the lab at http://lab runs at 100x")
    ticks = []
    for t in clock(12, 1):
        ticks.append(t)
        if len(ticks) == 3:
            labtime.sleep(4.5)  # one slow step (a plot, a network hiccup)
    assert len(ticks) == 13  # every step, as TCLabModel's adaptive clock gives them
    assert ticks == sorted(ticks)
    assert ticks[3] >= 6.5  # taken late, at the twin's time, not relabelled
    assert labtime.get_rate() == 100.0  # the twin's pace is not the client's to change
    note = capsys.readouterr().err
    assert note.count("came") == 1
    assert "late steps are taken at once (none skipped; the times are the twin's)" in note


def test_historian_sources_as_notebooks_write_them() -> None:
    lab = TCLabModel(synced=False)
    h = Historian(lab.sources)
    for t in range(5):
        lab.update(t)
        h.update(t)
    t, T1, _T2, _Q1, _Q2 = h.fields  # five columns, as notebooks unpack them
    assert t == [0, 1, 2, 3, 4]
    assert h.t is h.logdict["Time"] is t
    assert h.logdict["T1"] is T1
    assert h.after(3, ["Q1", "Q2"]) == [[0.0, 0.0], [0.0, 0.0]]

    def values() -> tuple[float, float, float]:
        return 21.0, 294.15, 1.2

    three = Historian([("T1", values), ("T1Kelvin", None), ("Power", None)])
    three.update(0)
    assert three.log == [(0, 21.0, 294.15, 1.2)]
    short = Historian([("a", lambda: [1]), ("b", None)])
    with pytest.raises(ValueError, match=r"the source of 'a' gave 1 value\(s\) for 2 names"):
        short.update()
    with pytest.raises(ValueError, match="needs a function"):
        Historian([("a", None)])


def test_historian_sessions_in_memory_as_tclabs() -> None:
    logs = []
    for module in (tclab, ours):
        value = iter(range(10))
        h = module.Historian([("a", lambda v=value: next(v))])
        h.update(1)
        h.update(2)
        h.new_session()
        h.update(1)
        first = h.at(1, ["a"])
        h.load_session(1)
        logs.append((len(h.get_sessions()), first, h.at(1, ["a"]), h.log))
    assert logs[0] == logs[1]
    # (tclab's load_session logs into the loaded session but leaves h.session at the newest;
    # ours names the session it logs into.)
    assert h.session == 1


def test_the_tag_database_answers_as_tclabs() -> None:
    from tclab.historian import TagDB as TheirTagDB

    from thermolab.tclab import TagDB

    answers = []
    for cls in (TheirTagDB, TagDB):
        db = cls()
        first = db.session
        db.record(0, "T1", 21.0)
        db.record(1, "T1", 22.5)
        db.new_session()
        db.record(0, "T1", 30.0)
        counts = [(i, n) for i, _, n in db.get_sessions()]
        answers.append((first, counts, db.get("T1"), db.get("T1", session=1), db.get("T1", 1, 1)))
        db.delete_session(1)
        answers.append([i for i, _, _ in db.get_sessions()])
        db.close()
    assert answers[0] == answers[2]
    assert answers[1] == answers[3] == [2]
