"""The lab's convergence figures are the library's on the same record (issue #24).

A run on panel 3's settings (WLSM on the Automatic square wave, 2000 samples)
goes through the lab; its CSV, as a student downloads it, goes through
``thermolab identify``. The samples to converge and the mean, maximum and
minimum of Ks and Ts the run page and the comparison show are the figures the
command prints: one function (:func:`thermolab.ident.table_figures.table_figures`)
makes both. On the paper's noise-free twin that is WLSM(1) of the paper:
converged at samples 86/87, Ks 0.140080 after convergence (over the whole run
the mean was 1.5 % low and the lab said "never").
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory
from .test_runs import person

# On SQLite alone: the library's figures on a stored record (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only


def _lab_and_cli(make_lab: LabFactory, tmp_path: Path, preset: str, body: dict[str, Any]) -> Any:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig(preset, clock=VirtualClock(), seed=7)

    lab = make_lab(opener=opener)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        answer = client.post("/api/rigs/twin/runs", json=body)
        assert answer.status_code == 201, answer.text
        run_id = answer.json()["id"]
        lab.runs.wait("twin", timeout=60)
        stored = client.get(f"/api/runs/{run_id}").json()["results"]["wlsm"]["stats"]
        compared = client.get(f"/api/runs/{run_id}/export.json").json()
        assert compared["methods"]["wlsm"]["result"]["stats"] == stored
        path = tmp_path / "run.csv"
        path.write_text(client.get(f"/api/runs/{run_id}/samples.csv").text, encoding="utf-8")
    settings = [f"--{name}={body[name]}" for name in ("gamma", "pmax") if name in body]
    cli = subprocess.run(
        [sys.executable, "-m", "thermolab", "identify", str(path), "--method", "wlsm",
         *settings, "--json"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return stored, json.loads(cli.stdout)["figures"]


@pytest.mark.parametrize(
    ("preset", "body", "converged_at"),
    [
        # Panel 3's defaults on the quick-start twin: the paper's WLSM(1).
        ("paper", {"signal": "square:0:4:0.1"}, {"K": 86, "tau": 87}),
        # The practical twin (noise, quantisation, jitter) with the paper's WLSM(2).
        ("paper-practical", {"signal": "square:0:4:0.1", "gamma": 0.7}, None),
    ],
)
def test_the_run_page_and_thermolab_identify_give_the_same_convergence_figures(
    make_lab: LabFactory,
    tmp_path: Path,
    preset: str,
    body: dict[str, Any],
    converged_at: dict[str, int] | None,
) -> None:
    request = {"dt": 1.0, "samples": 2000, "methods": ["wlsm"], **body}
    lab, cli = _lab_and_cli(make_lab, tmp_path, preset, request)
    for key in ("over", "last", "tol", "converged", "converged_at"):
        assert lab[key] == cli[key], key
    for name in ("K", "tau"):
        assert lab[name] == pytest.approx(cli[name], rel=1e-9), name
    if converged_at is not None:
        assert lab["over"] == "after_convergence"
        assert lab["converged_at"] == converged_at
        assert lab["K"]["mean"] == pytest.approx(0.140080, abs=5e-7)
