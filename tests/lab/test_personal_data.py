"""A person's export (``GET /api/me/export``): everything about them, nothing about others."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.lab.http.app import create_app

from .conftest import PASSWORD, LabFactory
from .test_runs import lab_request, person, twin_lab


def _keys(value: Any) -> set[str]:
    if isinstance(value, dict):
        return set(value) | {k for v in value.values() for k in _keys(v)}
    if isinstance(value, list):
        return {k for v in value for k in _keys(v)}
    return set()


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_a_students_export_holds_their_runs_samples_and_logins_and_no_one_elses(
    make_lab: LabFactory,
) -> None:
    lab = twin_lab(make_lab)
    ana, ben = person(lab, "ana"), person(lab, "ben")
    for who in (ana, ben):
        lab.access.request_control("twin", who)
        lab.runs.start("twin", who, lab_request(samples=30))
        lab.runs.wait("twin", timeout=30)
        lab.access.release("twin", who)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        client.post("/api/tokens", json={"name": "notebook", "readOnly": True})
        answer = client.get("/api/me/export")
        runs = client.get("/api/runs").json()
        tokens = client.get("/api/tokens").json()
    assert answer.status_code == 200
    assert answer.headers["content-disposition"] == 'attachment; filename="thermolab-ana.json"'
    export = json.loads(answer.content)
    tables = export["tables"]
    assert export["username"] == "ana"
    assert [row["username"] for row in tables["users"]] == ["ana"]
    assert sorted(row["id"] for row in tables["runs"]) == sorted(run["id"] for run in runs)
    assert {row["user_id"] for row in tables["runs"]} == {ana.user_id}
    (run,) = runs
    assert len(tables["samples"]) == run["samplesStored"] == 30
    assert {row["run_id"] for row in tables["samples"]} == {run["id"]}
    assert {row["run_id"] for row in tables["method_results"]} == {run["id"]}
    assert [row["name"] for row in tables["api_tokens"]] == [t["name"] for t in tokens]
    assert len(tables["sessions"]) == 1
    assert {row["user_id"] for row in tables["control_sessions"]} == {ana.user_id}
    assert not {key for key in _keys(export) if "hash" in key}  # no secret leaves
    assert "ben" not in answer.text
    assert ben.user_id not in {row.get("user_id") for rows in tables.values() for row in rows}
