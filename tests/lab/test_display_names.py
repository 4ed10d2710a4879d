"""Display names in the answers that name people: controller, queue, watchers, runs, session.

SQLite and PostgreSQL; the lab runs without devices on a manual clock.
"""

from __future__ import annotations

from collections.abc import Callable

from fastapi.testclient import TestClient

from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.runs import RunRequest
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory
from .test_runs import person

Clients = Callable[..., TestClient]


def test_the_answers_give_the_display_names_of_the_people_they_name(
    lab: Lab, app_client: Clients
) -> None:
    lab.users.add("tina", PASSWORD, "teacher", "Tina Araújo")
    lab.users.add("ana", PASSWORD, "student", "Ana Conceição")
    lab.users.add("bob", PASSWORD, "student")  # no display name
    tina, ana, bob = app_client("tina"), app_client("ana"), app_client("bob")
    assert ana.get("/api/session").json()["displayName"] == "Ana Conceição"
    assert bob.get("/api/session").json()["displayName"] is None
    assert ana.post("/api/rigs/twin/control").status_code == 200
    assert bob.post("/api/rigs/twin/control").status_code == 200
    seen = bob.get("/api/rigs/twin").json()["access"]
    assert (seen["controller"], seen["controllerName"]) == ("ana", "Ana Conceição")
    teacher = tina.get("/api/rigs/twin").json()
    assert [(q["username"], q["displayName"]) for q in teacher["queue"]] == [("bob", None)]
    watchers = {w["username"]: w["displayName"] for w in teacher["watcherList"]}
    assert watchers["ana"] == "Ana Conceição"
    # A class list renames a student: the next answer says so.
    course = tina.post("/api/courses", json={"name": "c1", "title": "C1"})
    assert course.status_code == 201
    upload = tina.put("/api/courses/c1/roster", content=b"username,display_name\nbob,Bob Dylan\n")
    assert upload.status_code == 200, upload.text
    queue = tina.get("/api/rigs/twin").json()["queue"]
    assert [(q["username"], q["displayName"]) for q in queue] == [("bob", "Bob Dylan")]


def test_runs_name_their_owner(make_lab: LabFactory) -> None:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=VirtualClock())

    lab = make_lab(opener=opener)
    tina = person(lab, "tina", "teacher")
    info = lab.users.add("ana", PASSWORD, "student", "Ana Conceição")
    ana = Principal(info.id, info.username, info.role)
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=20, signal="step:0:1@1"))
    lab.runs.wait("twin", timeout=30)
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        login = client.post("/api/session", json={"username": tina.username, "password": PASSWORD})
        assert login.status_code == 200
        listed = client.get("/api/runs").json()
        assert [(r["username"], r["displayName"]) for r in listed] == [("ana", "Ana Conceição")]
        assert client.get(f"/api/runs/{run.id}").json()["displayName"] == "Ana Conceição"
