"""A rig host's cable pulled 20 s mid-run: do its run and turn survive, how soon is it back?

Issue #23's "done when" figures for a lost link, measured on real processes
(the helpers of ``tests/agent/fleet.py``): ``thermolab serve`` with TLS and
the default grace (30 s), ``thermolab agent`` on a TCLab twin in a network
namespace of its own, whose cable (the lab's end of the veth pair) is set
down with ``ip link`` for ``--cut`` seconds while a student's run is going,
then up again. Each try prints: whether the run was still going and the
student still in control after the cut, the run's end (it must run to its
last sample), the samples stored against those asked (no gap), and the
seconds from the cable's return until the lab shows the host online and
healthy. Needs root (``ip netns``).

    .venv/bin/python benchmarks/bench_comeback.py               # 3 tries of 20 s
    .venv/bin/python benchmarks/bench_comeback.py --tries 1 --cut 10
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "agent"))
from fleet import Fleet, NetNs, make_fleet

GRACE = 30.0
"""``--agent-grace``'s default (lab.agents.hub.DEFAULT_GRACE)."""
DT = 0.2
TOML = """
[rig_defaults]
power_off_grace = 600
idle_limit = 600
control_time_limit = 3600

[access]
client_timeout = 600

[[rigs]]
id = "box"
spec = "sim:tclab"
agent = true
"""


def _controller(client: httpx.Client) -> str | None:
    access = client.get("/api/rigs/box").json()["access"]
    return str(access["role"]) if access.get("role") else None


def _try(
    fleet: Fleet, ns: NetNs, cut: float, tina: httpx.Client, ana: httpx.Client
) -> dict[str, Any]:
    fleet.wait_online(tina, "box")
    assert ana.post("/api/rigs/box/control").status_code == 200
    samples = int((3.0 + cut + 8.0) / DT)
    answer = ana.post(
        "/api/rigs/box/runs",
        json={"dt": DT, "samples": samples, "signal": "step:0:40@1", "methods": ["srm"]},
    )
    assert answer.status_code == 201, answer.text
    run_id = answer.json()["id"]
    time.sleep(3.0)
    ns.cut()
    time.sleep(cut)
    ns.mend()
    back = fleet.wait_online(tina, "box", timeout=120)
    going = ana.get(f"/api/runs/{run_id}").json()["status"] == "running"
    role = _controller(ana)
    record = ana.get(f"/api/runs/{run_id}").json()
    deadline = time.monotonic() + 120
    while record["status"] == "running" and time.monotonic() < deadline:
        time.sleep(0.3)
        record = ana.get(f"/api/runs/{run_id}").json()
    ks = [int(k) for k in ana.get(f"/api/runs/{run_id}/export.json").json()["samples"]["k"]]
    ana.delete("/api/rigs/box/control")  # the next try takes control afresh
    return {
        "back": back,
        "going": going,
        "role": role,
        "status": record["status"],
        "reason": record.get("endReason"),
        "stored": len(ks),
        "asked": samples,
        "gapless": ks == list(range(len(ks))),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cut", type=float, default=20.0, help="seconds the cable is out (20)")
    parser.add_argument("--tries", type=int, default=3, help="cuts, one run each (3)")
    args = parser.parse_args()
    why = NetNs.permitted()
    if why is not None:
        print(why, file=sys.stderr)
        return 1
    ns = NetNs()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        fleet = make_fleet(Path(tmp), TOML, extra_ip=ns.lab_ip)
        try:
            ns.make()
            fleet.start_lab(fleet.cert, fleet.key, grace=GRACE, agent_host=ns.lab_ip)  # type: ignore[attr-defined]
            fleet.start_agent("box", "sim:tclab", netns=ns.name)
            with (
                contextlib.closing(fleet.client("tina")) as tina,
                contextlib.closing(fleet.client("ana")) as ana,
            ):
                for number in range(1, args.tries + 1):
                    result = _try(fleet, ns, args.cut, tina, ana)
                    results.append(result)
                    print(
                        f"try {number}: cable out {args.cut:g} s; back {result['back']:.2f} s "
                        f"after it returned; after the cut the run was "
                        f"{'going' if result['going'] else 'OVER'} and ana's role "
                        f"{result['role']}; the run ended {result['status']} "
                        f"({result['reason']}), {result['stored']}/{result['asked']} samples, "
                        f"{'no gap' if result['gapless'] else 'A GAP'}",
                        flush=True,
                    )
        finally:
            fleet.stop()
            ns.remove()
    backs = [r["back"] for r in results]
    kept = sum(
        1
        for r in results
        if r["going"] and r["role"] == "controller" and r["stored"] == r["asked"] and r["gapless"]
    )
    print(
        f"{kept} of {len(results)} runs and turns kept through a {args.cut:g} s cut; back after "
        f"the cable: median {statistics.median(backs):.2f} s, max {max(backs):.2f} s"
    )
    return 0 if kept == len(results) and max(backs) < 2.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
