"""Table I through the browser at a speed-up, beside ``thermolab reproduce table1``.

Runs the browser test ``tests/web/test_table1_browser.py`` (a real lab at the
speed-up it declares, Chromium, a student running panels 1-3 on the noise-free
twin), which writes the figures it read off the comparison page and the wall
time of each run; then times ``thermolab reproduce table1`` on the same rows as
a command, and prints both side by side: the figures (which the test already
requires to print the same digits) and the time each took.

    .venv/bin/python benchmarks/bench_table1_browser.py

Needs Playwright and Chromium (as the browser tests do).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = ("SRM", "LSM(1)", "MALSM", "WLSM(1)", "WLSM(2)", "WLSM(3)")
PANEL_RUN = {"SRM": "SRM, LSM(1)", "LSM(1)": "SRM, LSM(1)"}


def browser_figures() -> tuple[dict[str, object], float]:
    """The page's figures and run times from the browser test, and its whole wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "figures.json"
        started = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "tests/web/test_table1_browser.py", "-q",
             "-p", "no:randomly", "-k", "three_panels"],
            cwd=ROOT, env={**_env(), "THERMOLAB_TABLE1_FIGURES": str(out)},
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        wall = time.perf_counter() - started
        if proc.returncode != 0 or not out.exists():
            sys.exit(f"the browser test did not pass:\n{proc.stdout[-3000:]}{proc.stderr[-2000:]}")
        return json.loads(out.read_text(encoding="utf-8")), wall


def cli_figures() -> tuple[dict[str, dict[str, object]], float]:
    """``thermolab reproduce table1 --json`` on the same rows, and its wall time."""
    started = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "thermolab", "reproduce", "table1", "--runs", ",".join(ROWS),
         "--json"],
        cwd=ROOT, env=_env(), capture_output=True, text=True, check=True,
    )  # fmt: skip
    wall = time.perf_counter() - started
    rows = {row["run"]: row for row in json.loads(proc.stdout)["rows"]}
    return rows, wall


def _env() -> dict[str, str]:
    import os

    return dict(os.environ)


def _printed(stats: dict[str, float]) -> str:
    return _three(" / ".join(f"{stats[k]:.6f}" for k in ("mean", "max", "min")))


def _three(text: str) -> str:
    """Mean / max / min, or one value when the three print alike."""
    parts = text.split(" / ")
    return parts[0] if len(set(parts)) == 1 else text


def _mark(label: str, ours: str, theirs: str) -> str:
    if ours == theirs:
        return "="
    if label == "conv":
        near = all(
            abs(int(a) - int(b)) <= 1
            for a, b in zip(ours.split(" / "), theirs.split(" / "), strict=True)
        )
        return "~" if near else "x"
    return "x"


def main() -> None:
    page, browser_wall = browser_figures()
    cli, cli_wall = cli_figures()
    speedup = page["speedup"]
    walls: dict[str, float] = page["walls"]  # type: ignore[assignment]
    shown: dict[str, dict[str, str]] = page["page"]  # type: ignore[assignment]
    samples: dict[str, int] = page["samples"]  # type: ignore[assignment]
    print(f"Table I: the browser (twin at {speedup:g}x) beside `thermolab reproduce table1`\n")
    print(f"{'row':8} {'':4} {'page (6 decimals)':44} {'reproduce table1':44}")
    for name in ROWS:
        row = cli[name]
        page_row = shown[name]
        k_cli = _printed(row["K"])  # type: ignore[arg-type]
        k_page = page_row["Klast"].split(": ")[-1] if name == "SRM" else page_row["K"]
        conv = row["converged_at"]
        for label, ours, theirs in (
            ("Ks", _three(k_page), k_cli),
            ("Ts", _three(page_row["tau"]), _printed(row["tau"])),  # type: ignore[arg-type]
            ("conv", page_row["conv"], "" if conv is None else f"{conv['K']} / {conv['tau']}"),  # type: ignore[index]
        ):
            if label == "conv" and not theirs:
                continue
            mark = _mark(label, ours, theirs)
            print(f"{name if label == 'Ks' else '':8} {label:4} {ours:44} {theirs:44} {mark}")
    print("\n(SRM's Ks: the page's last-sample gain, the figure Table I prints; page conv is")
    print(" counted on the run itself, the command's on a pilot record: ~ within 1 sample)\n")
    print(f"{'run':12} {'samples':>8} {'browser run (s)':>16} {'simulated (s)':>14}")
    for run, wall in walls.items():
        first = run.split(",")[0]
        n = samples[first]
        print(f"{run:12} {n:8d} {wall:16.2f} {n * 1.0:14.0f}")
    total = sum(walls.values())
    print(f"{'all runs':12} {'':8} {total:16.2f}")
    print(f"\nbrowser test, start of the lab to the last figure: {browser_wall:.1f} s")
    print(f"thermolab reproduce table1 --runs {','.join(ROWS)}: {cli_wall:.2f} s (command)")


if __name__ == "__main__":
    main()
