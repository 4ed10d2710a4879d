"""A lab restart during a remote run: the host's late end is identified as any other.

The lab stores the run interrupted when it starts again; the rig host, which
ENDed the run by itself when the link went, uploads the samples and the end
once the link is back. That end stores the run's status and, as an
in-process run's end does, each method's result with its figures and the
run's timing.
Real processes: a TLS lab (``thermolab serve``, stopped with SIGTERM and
served again on the same port) and a ``thermolab agent`` driving a twin.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from .fleet import ONE_REMOTE_BOX, make_fleet

pytestmark = pytest.mark.slow

GRACE = 2.0


def test_the_hosts_end_after_a_lab_restart_stores_the_runs_results(tmp_path: Path) -> None:
    fleet = make_fleet(tmp_path, ONE_REMOTE_BOX)
    cert, key = fleet.cert, fleet.key  # type: ignore[attr-defined]
    try:
        fleet.start_lab(cert, key, grace=GRACE)
        port = urlsplit(fleet.url).port
        fleet.start_agent("box", "sim:tclab")
        with (
            contextlib.closing(fleet.client("tina")) as teacher,
            contextlib.closing(fleet.client("ana")) as ana,
        ):
            fleet.wait_online(teacher, "box")
            assert ana.post("/api/rigs/box/control").status_code == 200
            run = ana.post(
                "/api/rigs/box/runs",
                json={
                    "dt": 0.2,
                    "samples": 3000,
                    "signal": "step:0:40@0.4",
                    "methods": ["srm", "lsm"],
                },
            )
            assert run.status_code == 201, run.text
            run_id = run.json()["id"]
            deadline = time.monotonic() + 60
            while ana.get(f"/api/runs/{run_id}").json()["samplesStored"] < 20:
                assert time.monotonic() < deadline, "no samples came from the host"
                time.sleep(0.2)
        fleet.stop_lab()
        fleet.start_lab(cert, key, grace=GRACE, port=port)
        with (
            contextlib.closing(fleet.client("tina")) as teacher,
            contextlib.closing(fleet.client("ana")) as ana,
        ):
            fleet.wait_online(teacher, "box", timeout=90)
            deadline = time.monotonic() + 90
            while True:
                record = ana.get(f"/api/runs/{run_id}").json()
                if record["status"] not in ("running", "interrupted"):
                    break
                assert time.monotonic() < deadline, record
                time.sleep(0.3)
        # The host ENDed the run when the link went; its end overwrote "interrupted", and
        # names the real cause: the lab's server went (its machine refused the redials),
        # not the host's link (issue #23).
        assert record["status"] == "stopped", record
        assert record["endReason"] == "owner_gone: no lab worker owned the rigs for over 2 s"
        log = (fleet.data_dir / "agent-box.log").read_text(errors="replace")
        assert "ENDing run" in log, log
        # ... and the lab identified it on the uploaded samples, as in-process.
        assert set(record["results"]) == {"srm", "lsm"}, record
        lsm = record["results"]["lsm"]
        # Its final estimate is of every stored sample (valid or saying why not: a
        # few seconds of the slow kit twin may not excite it).
        assert lsm["latest"]["k"] == record["samplesStored"] - 1, lsm
        assert lsm["latest"]["valid"] or lsm["latest"]["extras"]["reason"], lsm
        assert "stats" in lsm
        srm = record["results"]["srm"]  # an estimate, or why there is none
        assert srm["latest"] is not None or srm.get("error")
        # ... and its timing judged on the uploaded samples, as an in-process run's end.
        timing = record["timing"]
        assert timing is not None, record
        assert (timing["rig"], timing["maxLateness"]) == ("twin", None)
        assert timing["periodSpread"] < 0.01
        assert timing["warnings"] == []
    finally:
        fleet.stop()
