"""A run's channels carry their unit and role: stored with the run, in every way it is read.

The channel specs (:class:`thermolab.records.ChannelSpec`) are kept with the
run's row when it is made (:func:`thermolab.lab.runs.store.add_run`): the
standard channels in the rig's own units, then whatever a rig or a controller
publishes. ``GET /api/runs/{id}`` (and so the live stream's ``run`` message,
built from the same :class:`RunOut`), ``export.json`` and the CSV all read them.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.control import tune
from thermolab.errors import ThermoLabError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.http.routers.runs import RunOut
from thermolab.lab.runs import samples_csv
from thermolab.lab.runs.recorder import DatabaseRecorder
from thermolab.lab.runs.store import add_run, run_channels
from thermolab.lab.service import Lab
from thermolab.records import RUN_CHANNELS, ChannelSpec, read_record
from thermolab.rigs import Rig, TwinRig, VirtualClock
from thermolab.runner import ControlLoop, Experiment

from .conftest import PASSWORD, LabFactory

KIT = (0.6, 140.0, 15.9)  # the kit's FOPDT figures (twin preset "tclab")


def twin_lab(make_lab: LabFactory) -> Lab:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper" if rig.id == "twin" else "tclab", clock=VirtualClock())

    return make_lab(opener=opener)


def person(lab: Lab, name: str) -> Principal:
    info = lab.users.add(name, PASSWORD, "student")
    return Principal(info.id, info.username, info.role)


def described(channels: list[dict[str, Any]]) -> dict[str, tuple[str, str]]:
    return {c["name"]: (c["unit"], c["role"]) for c in channels}


def test_a_started_run_describes_its_channels_in_the_rigs_units(make_lab: LabFactory) -> None:
    lab = twin_lab(make_lab)
    person(lab, "ana")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        client.post("/api/rigs/other/control")  # the kit's twin: % in, degC out
        started = client.post(
            "/api/rigs/other/runs", json={"dt": 1, "samples": 20, "setpoint": 30.0}
        )
        assert started.status_code == 201, started.text
        lab.runs.wait("other", 60)
        run_id = started.json()["id"]
        run = client.get(f"/api/runs/{run_id}").json()
        exported = client.get(f"/api/runs/{run_id}/export.json").json()
        text = client.get(f"/api/runs/{run_id}/samples.csv").text
    # What START answered is what the live stream's run-start message carries (RunOut).
    assert started.json()["channels"] == run["channels"]
    names = [c["name"] for c in run["channels"]]
    assert names == [c.name for c in RUN_CHANNELS]
    units = described(run["channels"])
    assert units["t"] == ("s", "time")
    assert units["u"] == ("%", "input")
    assert units["y"] == ("degC", "output")
    assert units["k"] == ("", "index")
    assert exported["channels"] == run["channels"]
    assert next(csv.reader(io.StringIO(text))) == names
    assert len(exported["samples"]["y"]) == 20


def test_a_pids_channels_are_stored_with_their_units_and_roles(make_lab: LabFactory) -> None:
    lab = twin_lab(make_lab)
    ana = person(lab, "ana")
    lab.access.request_control("other", ana)
    rig = lab.hub.driver("other")
    assert rig is not None
    loop = ControlLoop(tune(KIT, "simc").gains, setpoint=30.0)
    channels = Experiment(rig, 1.0, 1, controller=loop).channels
    published = lab.hub.published("other")
    declared = run_channels(
        published.input_unit, published.output_unit, channels[len(RUN_CHANNELS) :]
    )
    settings = {"dt": 1.0, "samples": 40, "signal": None, "setpoint": None, "methods": []}
    with lab.access.controlled("other", ana, "start a run") as turn:
        run_id = add_run(
            turn.session, turn.control, ana, turn.now, settings=settings, meta={}, channels=declared
        )
    recorder = DatabaseRecorder(lab.db, run_id, channels=channels)
    result = Experiment(rig, 1.0, 40, controller=loop, recorder=recorder).run()
    assert result.ok

    record = lab.runs.record(run_id)
    units = described(RunOut.of(record).model_dump(mode="json")["channels"])
    assert units["r"] == ("degC", "setpoint")
    assert units["u_pid"] == ("%", "other")
    assert units["e"] == ("degC", "error")
    assert units["auto"] == ("", "other")
    assert units["u"] == ("%", "input")

    exported = lab.runs.export(run_id, ana)
    assert described(exported["channels"]) == units
    assert exported["samples"]["auto"] == [1] * 40  # an integer channel stays one
    assert exported["samples"]["r"] == [30.0] * 40
    stored, rows = lab.runs.record_rows(run_id, ana)
    names = [c.name for c in stored]
    assert names[len(RUN_CHANNELS) : len(RUN_CHANNELS) + 4] == ["r", "u_pid", "e", "auto"]
    values = list(rows)
    e = [row[len(RUN_CHANNELS) + 2] for row in values]
    assert all(
        math.isclose(ei, 30.0 - row[2], abs_tol=1e-9) for ei, row in zip(e, values, strict=True)
    )


def test_extra_channels_of_a_rig_are_stored_and_exported_by_name(
    make_lab: LabFactory, tmp_path: Any
) -> None:
    """Channels a rig publishes (a set point, a second sensor) reach the store and both exports."""
    lab = twin_lab(make_lab)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    extra = (ChannelSpec("r", "V", "setpoint"), ChannelSpec("y2", "degC", "output"))
    settings = {"dt": 1.0, "samples": 3, "signal": None, "setpoint": 2.0, "methods": []}
    with lab.access.controlled("twin", ana, "start a run") as turn:
        run_id = add_run(
            turn.session,
            turn.control,
            ana,
            turn.now,
            settings=settings,
            meta={},
            channels=run_channels("V", "V", extra),
        )
    recorder = DatabaseRecorder(lab.db, run_id, channels=(*RUN_CHANNELS, *extra))
    recorder.open()
    for k in range(3):
        recorder.write(k, float(k), 2.0, 0.1 * k, k + 0.01, 0.01, 0.0, 5.0, math.nan)
    recorder.close()
    stored, rows = lab.runs.record_rows(run_id, ana)
    path = tmp_path / "run.csv"
    path.write_text("".join(samples_csv(stored, rows)), encoding="utf-8")
    text = path.read_text(encoding="utf-8")
    header, first = text.splitlines()[:2]
    assert header == "t,u,y,k,t_read,jitter,lateness,r,y2"
    assert first == "0,2.0,0.0,0,0.01,0.01,0.0,5.0,nan"
    assert list(read_record(path).columns)[-2:] == ["r", "y2"]
    exported = lab.runs.export(run_id, ana)
    assert exported["channels"][-2:] == [c.to_dict() for c in extra]
    assert exported["samples"]["r"] == [5.0, 5.0, 5.0]
    assert exported["samples"]["y2"] == [None, None, None]  # JSON has no NaN
    with pytest.raises(ThermoLabError, match="RUN_CHANNELS"):
        DatabaseRecorder(lab.db, run_id, channels=extra)
