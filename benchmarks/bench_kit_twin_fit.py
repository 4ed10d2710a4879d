"""The two-heater twin on real TCLab records: fitted constants beside the published ones.

Every record of ``tests/real_records/kit_records.py`` (six fitting records,
two held out; one heater or two) is replayed on the twin: its heaters held
from each row's time, the kit at rest at each sensor's first readings. It
prints the RMS error (°C) of T1 and T2 over the whole record and over the
steps of each heater (a step of Q1 scored on T1, of Q2 on T2, from the step to
the next change of either heater) for

* ``KIT_FIT``: :data:`thermolab.kit_physics.KIT_FIT`, fitted to the fitting records;
* ``tclab``: the peer, the ``tclab`` package's own ``TCLabModel`` (its published
  constants, Euler steps of 0.2 s) driven row by row on the record's own time
  stamps, shifted to each sensor's ambient (the model is linear); with
  ``tclab`` missing, the published constants on :func:`thermolab.kit_physics.simulate_kit`.

``--refit`` fits the constants again (about two minutes on a 2-core box) and
scores them instead of ``KIT_FIT``, printing them as code; ``--detail`` adds
each step's RMS; ``--alone`` also fits each record alone (another two minutes)
and prints its RMS and constants: how far one kit's constants are from
another's.

Run from the repository root::

    .venv/bin/python benchmarks/bench_kit_twin_fit.py
    .venv/bin/python benchmarks/bench_kit_twin_fit.py --refit --detail
    .venv/bin/python benchmarks/bench_kit_twin_fit.py --alone
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "real_records"))

import kit_records

from thermolab.kit_physics import KIT_FIT, KitConstants, simulate_kit


def tclab_model(record: kit_records.KitRecord) -> tuple[np.ndarray, np.ndarray] | None:
    """The ``tclab`` package's ``TCLabModel`` on a record's heaters (None without ``tclab``)."""
    try:
        import tclab
    except ImportError:
        return None
    with contextlib.redirect_stdout(io.StringIO()):
        lab = tclab.TCLabModel(synced=False)
    T1, T2 = np.empty(record.t.size), np.empty(record.t.size)
    for i, t in enumerate(record.t):
        lab.update(float(t))
        # The sensors' noise-free temperatures: the kit's, before the converter.
        T1[i], T2[i] = lab._T1, lab._T2
        lab.Q1(float(record.q1[i]))
        lab.Q2(float(record.q2[i]))
    room1, room2 = record.ambient
    return T1 - lab.Ta + room1, T2 - lab.Ta + room2


def published(record: kit_records.KitRecord) -> tuple[np.ndarray, np.ndarray]:
    """The peer's sensors: ``tclab``'s model, or the published constants on ours."""
    theirs = tclab_model(record)
    if theirs is not None:
        return theirs
    return simulate_kit(record.t, record.q1, record.q2, KitConstants(), ambient=record.ambient)


def _figure(x: float) -> str:
    return "    –" if math.isnan(x) else f"{x:5.2f}"


def main(argv: list[str] | None = None) -> int:
    """Print the table; ``--refit`` first fits the constants again."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--refit", action="store_true", help="fit the constants again")
    parser.add_argument("--detail", action="store_true", help="each step's RMS too")
    parser.add_argument("--alone", action="store_true", help="fit each record alone too")
    args = parser.parse_args(argv)

    constants = KIT_FIT
    if args.refit:
        start = time.perf_counter()
        constants = kit_records.fit()
        print(f"refitted in {time.perf_counter() - start:.0f} s on the fitting records:")
        fitted = ", ".join(f"{n}={getattr(constants, n):.4g}" for n in kit_records.FITTED)
        print(f"    KitConstants({fitted})")
        print()
    peer = "tclab" if tclab_model(kit_records.records()[0]) is not None else "published"
    name = "refit" if args.refit else "KIT_FIT"
    print(f"RMS error, °C: {name} | {peer} (the published constants)")
    print(f"{'record':26s} {'heaters':>7s} {'set':>8s}   {'T1':>13s} {'T2':>13s}"
          f" {'Q1 steps':>13s} {'Q2 steps':>13s}")  # fmt: skip
    totals: dict[tuple[bool, str], list[float]] = {}
    for record in kit_records.records():
        ours = kit_records.score(record, constants)
        theirs = kit_records.score_on(record, published(record))
        cells = []
        for key, a, b in (
            ("T1", ours.T1, theirs.T1),
            ("T2", ours.T2, theirs.T2),
            ("Q1", ours.over_steps("Q1"), theirs.over_steps("Q1")),
            ("Q2", ours.over_steps("Q2"), theirs.over_steps("Q2")),
        ):
            cells.append(f"{_figure(a)} | {_figure(b)}")
            if not math.isnan(a):
                totals.setdefault((record.spec.held_out, key + " ours"), []).append(a)
                totals.setdefault((record.spec.held_out, key + " peer"), []).append(b)
        role = "held out" if record.spec.held_out else "fit"
        print(f"{record.spec.name:26s} {record.heaters:7d} {role:>8s}   " + " ".join(cells))
        if args.detail:
            for (heater, at, a), (_, _, b) in zip(ours.steps, theirs.steps, strict=True):
                print(f"    {heater} step at {at:6.0f} s: {_figure(a)} | {_figure(b)}")
    print()
    for held_out in (False, True):
        part = "held out" if held_out else "fitting"
        line = []
        for key in ("T1", "T2", "Q1", "Q2"):
            a, b = totals.get((held_out, key + " ours")), totals.get((held_out, key + " peer"))
            if a and b:
                line.append(f"{key} {np.sqrt(np.mean(np.square(a))):.2f} | "
                            f"{np.sqrt(np.mean(np.square(b))):.2f}")  # fmt: skip
        print(f"RMS over the {part} records: " + ", ".join(line))
    if args.alone:
        alone()
    return 0


def alone() -> None:
    """Each record's own fit: its RMS (°C) and constants, the spread between kits."""
    print()
    print("each record fitted alone: RMS T1, T2 (°C) and its constants")
    for record in kit_records.records():
        own = kit_records.fit([record])
        s = kit_records.score(record, own)
        fitted = ", ".join(f"{n}={getattr(own, n):.3g}" for n in kit_records.FITTED)
        print(f"{record.spec.name:26s} {_figure(s.T1)} {_figure(s.T2)}   {fitted}")


if __name__ == "__main__":
    raise SystemExit(main())
