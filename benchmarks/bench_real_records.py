"""Real records: is a trusted model right, and is a right model trusted?

Every record of the real-record corpus (``tests/real_records/corpus.py``: the
reader spec of each file in ``../shared/real-records/``) is identified by
``thermolab identify FILE --method M --json`` with every setting at its
default, in this process, and compared with the corpus's reference fits (a
first order plus dead time fitted with SciPy on the record's own time stamps,
and python-control's peer fit where it fits as well; neither uses
``thermolab.ident``). "Right" is within ±10 % of K and tau and ±5 s of theta of
either reference.

It prints, per method, over the whole corpus and over its held-out part: right
and trusted / right but flagged / wrong and flagged (a refusal counts here) /
wrong but trusted, and the median |error| of K (%), tau (%) and theta (s)
against the SciPy fit over the results that have a model. ``--detail`` adds one
line per run.

Run from the repository root::

    .venv/bin/python benchmarks/bench_real_records.py
    .venv/bin/python benchmarks/bench_real_records.py --methods lsm oe --detail
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "real_records"))

import corpus

from thermolab.cli import main as thermolab

METHODS = ("srm", "lsm", "oe", "malsm", "wlsm", "blockls")
KINDS = ("right, trusted", "right, flagged", "wrong, flagged", "WRONG BUT TRUSTED")


@dataclass
class Outcome:
    """One run: the record, the method, the verdict and the errors against the SciPy fit."""

    record: str
    method: str
    held_out: bool
    kind: str
    K: float | None
    tau: float | None
    theta: float | None
    errors: tuple[float, float, float] | None
    note: str


def identify(path: Path, method: str) -> tuple[int, dict[str, Any] | None, str]:
    """``thermolab identify PATH --method METHOD --json``: status, JSON (or None), stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = thermolab(["identify", str(path), "--method", method, "--json"])
    return status, (json.loads(out.getvalue()) if status == 0 else None), err.getvalue()


def _number(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


def classify(spec: corpus.Spec, method: str, path: Path, peer: bool) -> Outcome:
    """Run one method on one record and sort the result into :data:`KINDS`."""
    status, s, err = identify(path, method)
    if s is None:
        return Outcome(
            spec.name, method, spec.held_out, KINDS[2], None, None, None, None,
            f"refused (exit {status}): {err.strip().splitlines()[-1] if err.strip() else ''}",
        )  # fmt: skip
    K, tau, theta = _number(s.get("K")), _number(s.get("tau")), _number(s.get("theta"))
    refs = corpus.references(spec, peer=peer)
    right = any(r.right(K, tau, theta) for r in refs)
    trusted = bool(s.get("trusted"))
    kind = KINDS[(0 if trusted else 1) if right else (3 if trusted else 2)]
    ref = refs[0]
    errors = None
    if K is not None and tau is not None:
        errors = (
            100 * abs(K / ref.K - 1), 100 * abs(tau / ref.tau - 1), abs((theta or 0.0) - ref.theta),
        )  # fmt: skip
    verdict = s.get("verdict") or {}
    notes = [str(w) for w in verdict.get("reasons") or s.get("warnings") or []]
    return Outcome(
        spec.name, method, spec.held_out, kind, K, tau, theta, errors,
        "; ".join(n[:90] for n in notes) or (s.get("reason") or ""),
    )  # fmt: skip


def table(outcomes: list[Outcome], methods: tuple[str, ...]) -> str:
    """The Markdown table: counts per kind and median errors, per method."""
    lines = [
        "| method | records | " + " | ".join(KINDS) + " | median dK % | median dtau % | "
        "median dtheta s |",
        "|---|---|" + "---|" * (len(KINDS) + 3),
    ]
    for method in methods:
        mine = [o for o in outcomes if o.method == method]
        counts = [sum(o.kind == k for o in mine) for k in KINDS]
        errs = np.array([o.errors for o in mine if o.errors is not None]).reshape(-1, 3)
        med = [f"{np.median(errs[:, j]):.1f}" if errs.size else "-" for j in range(3)]
        lines.append(
            f"| {method} | {len(mine)} | " + " | ".join(map(str, counts)) + " | "
            + " | ".join(med) + " |"
        )  # fmt: skip
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--no-peer", action="store_true", help="SciPy's reference fit only")
    parser.add_argument("--detail", action="store_true", help="one line per run")
    args = parser.parse_args()
    if not corpus.FOLDER.is_dir():
        raise SystemExit(f"no corpus: {corpus.FOLDER} is absent")
    methods = tuple(args.methods)
    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory() as folder:
        for spec in corpus.SPECS:
            path = corpus.write_tuy(corpus.load(spec), Path(folder) / "record.csv")
            refs = corpus.references(spec, peer=not args.no_peer)
            shown = "; ".join(
                f"{r.source} K {r.K:.4g} tau {r.tau:.1f} theta {r.theta:.1f}" for r in refs
            )
            print(f"{spec.name:28} {'(held out) ' if spec.held_out else ''}{shown}")
            for method in methods:
                outcomes.append(classify(spec, method, path, peer=not args.no_peer))
    if args.detail:
        print()
        for o in outcomes:
            model = (
                "no model" if o.K is None or o.tau is None
                else f"K {o.K:.4g} tau {o.tau:.1f} theta {o.theta or 0:.1f}"
            )  # fmt: skip
            print(f"{o.record:28} {o.method:8} {o.kind:18} {model:34} {o.note[:160]}")
    n_held = sum(s.held_out for s in corpus.SPECS)
    print(f"\nAll {len(corpus.SPECS)} records:\n")
    print(table(outcomes, methods))
    print(f"\nHeld out ({n_held} records, no rule tuned on them):\n")
    print(table([o for o in outcomes if o.held_out], methods))


if __name__ == "__main__":
    main()
