"""Benchmark of reading run records (``thermolab.records``) and ``thermolab identify``.

For each size (10^6 and 10^7 rows by default) a record in the runner's format
(``t,u,y,k,t_read,jitter,lateness``, shortest round-trip floats) of the
paper's model under the 4↔6 V square wave with a little noise is written once
to a cache folder, then three child processes are timed in turn, each in a
fresh interpreter so that its peak memory is its own:

1. ``thermolab identify FILE --method M --json`` for each method asked
   (``--methods``, default ``lsm blockls``; the whole command: start-up,
   reading, identification with its defaults, printing);
2. ``thermolab.records.read_record(FILE)`` alone, reading the three columns
   ``identify`` needs (start-up and reading only);
3. the peer: ``pandas.read_csv(FILE)`` (default engine, every column).

It prints wall time, CPU time and peak memory (``ru_maxrss`` of each child,
from ``os.wait4``), the machine's load average around each size (on a shared
machine wall times follow the load; CPU times much less), and whether the
issue's target is met: 10^7 rows identified in under 10 s and under 1.5 GB.

Run from the repository root::

    .venv/bin/python benchmarks/bench_records.py                   # 10^6 and 10^7 rows
    .venv/bin/python benchmarks/bench_records.py --rows 1000000 --repeat 3
    .venv/bin/python benchmarks/bench_records.py --methods lsm oe
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from thermolab.records import RUN_CHANNELS, channel_names
from thermolab.simulation import simulate_first_order

TARGET_SECONDS = 10.0
TARGET_BYTES = 1.5e9
TARGET_ROWS = 10**7

READ_ONLY = (
    "import sys; from thermolab.records import read_record; "
    "r = read_record(sys.argv[1], channels=()); print(r.n)"
)
PANDAS = "import sys, pandas; df = pandas.read_csv(sys.argv[1]); print(len(df))"


def make_record(path: Path, rows: int) -> None:
    """Write a runner-format record of ``rows`` samples (pyarrow's writer, for speed)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    rng = np.random.default_rng(2024)
    dt = 1.0
    k = np.arange(rows)
    u = np.where((k // 50) % 2 == 0, 6.0, 4.0)
    y = simulate_first_order(u, 0.14, 250.0, dt) + rng.normal(0.0, 1e-3, rows)
    jitter = rng.normal(0.0, 1e-4, rows)
    columns = {
        "t": k * dt,
        "u": u,
        "y": y,
        "k": k,
        "t_read": k * dt + jitter,
        "jitter": jitter,
        "lateness": np.abs(rng.normal(0.0, 1e-4, rows)),
    }
    assert tuple(columns) == channel_names(RUN_CHANNELS)
    table = pa.table(columns)
    tmp = path.with_suffix(".tmp")
    pacsv.write_csv(
        table, str(tmp), write_options=pacsv.WriteOptions(quoting_style="none", batch_size=65536)
    )
    tmp.replace(path)


def measure(argv: list[str]) -> tuple[float, float, float, str]:
    """Run a child; return (wall seconds, peak resident bytes, CPU seconds, last output line).

    CPU time (user + system, all threads) moves less than wall time with the
    load of a shared machine.
    """
    with tempfile.TemporaryFile() as out_file, tempfile.TemporaryFile() as err_file:
        start = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=out_file, stderr=err_file)
        # wait4 gives this child's own rusage (RUSAGE_CHILDREN would mix all children).
        _, status, usage = os.wait4(proc.pid, 0)
        elapsed = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out_file.seek(0)
        err_file.seek(0)
        out, err = out_file.read().decode(), err_file.read().decode()
    if proc.returncode != 0:
        raise SystemExit(f"{argv[:4]} failed ({proc.returncode}): {err.strip()}")
    lines = out.strip().splitlines()
    cpu = usage.ru_utime + usage.ru_stime
    return elapsed, usage.ru_maxrss * 1024.0, cpu, (lines[-1] if lines else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--rows", type=int, nargs="+", default=[10**6, 10**7], help="record sizes (1e6 1e7)"
    )
    parser.add_argument("--repeat", type=int, default=1, help="best of N per child (1)")
    parser.add_argument(
        "--methods", nargs="+", default=["lsm", "blockls"], help="methods identified (lsm blockls)"
    )
    parser.add_argument(
        "--folder",
        type=Path,
        default=Path(tempfile.gettempdir()) / "thermolab-bench-records",
        help="where the records are cached",
    )
    args = parser.parse_args()
    args.folder.mkdir(parents=True, exist_ok=True)
    python = sys.executable
    print(
        f"target: {TARGET_ROWS:.0e} rows identified by `thermolab identify` in under "
        f"{TARGET_SECONDS:.0f} s and {TARGET_BYTES / 1e9:.1f} GB (peak resident memory)"
    )
    verdicts = []
    for rows in args.rows:
        path = args.folder / f"record-{rows}.csv"
        if not path.exists():
            start = time.perf_counter()
            make_record(path, rows)
            print(f"wrote {path} in {time.perf_counter() - start:.1f} s")
        size = path.stat().st_size
        load = os.getloadavg()[0]
        print(f"\n{rows:,} rows, {size / 1e6:.0f} MB ({path}); load average {load:.1f}")
        children = {
            f"thermolab identify --method {m}": [
                python, "-m", "thermolab", "identify", str(path), "--method", m, "--json",
            ]
            for m in args.methods
        }  # fmt: skip
        children["thermolab.records.read_record (t,u,y)"] = [python, "-c", READ_ONLY, str(path)]
        children["peer: pandas.read_csv (all columns)"] = [python, "-c", PANDAS, str(path)]
        results = {}
        for name, argv in children.items():
            runs = [measure(argv) for _ in range(args.repeat)]
            results[name] = min(runs)
            seconds, peak, cpu, _ = results[name]
            print(f"   {name:<42} {seconds:7.2f} s   cpu {cpu:7.2f} s   peak {peak / 1e6:7.0f} MB")
        print(f"   load average after: {os.getloadavg()[0]:.1f}")
        if rows == TARGET_ROWS:
            for m in args.methods:
                seconds, peak, cpu, _ = results[f"thermolab identify --method {m}"]
                met = seconds < TARGET_SECONDS and peak < TARGET_BYTES
                verdicts.append(
                    f"{m}: {seconds:.2f} s ({cpu:.2f} s CPU), {peak / 1e9:.2f} GB -> "
                    f"{'met' if met else 'NOT met'}"
                    + ("" if met or cpu >= TARGET_SECONDS else " on the wall clock (CPU within)")
                )
    if verdicts:
        print("\ntarget, 10^7 rows under 10 s and 1.5 GB:\n   " + "\n   ".join(verdicts))


if __name__ == "__main__":
    main()
