"""Course notebooks cell by cell: the lab's kit twin (``thermolab.tclab``) against ``TCLabModel``.

The yardstick of issue #22: a notebook written for the ``tclab`` package
should run against a lab rig with only its import changed. For each notebook
(``*.ipynb``) or script (``*.py``, one cell) in the folder given, this runs
every code cell with nbclient in a fresh kernel, twice:

* **model** — as written, against the ``tclab`` package (1.0.0) with its
  offline ``TCLabModel`` in place of the kit: ``tclab.TCLab`` and
  ``setup(connected=True)`` give ``TCLabModel``, at ``--speedup`` (a
  notebook's own ``setup(connected=False, speedup=...)`` keeps its own);
* **lab** — with ``import tclab`` / ``from tclab import`` turned into
  ``thermolab.tclab``, against a ``thermolab serve`` started here with the
  rig ``--rig`` names (the kit's two-heater twin ``sim:kit`` by default, so
  ``T2``/``Q2``/``P2`` work as on a kit; ``sim:tclab`` is the one-heater
  twin) at ``--speedup``, reached through
  ``THERMOLAB_URL``/``THERMOLAB_TOKEN``/``THERMOLAB_RIG``.

Scripts written for a kit pace themselves with ``time.sleep`` in real time;
in both runs a hidden first cell scales ``time.sleep`` by ``1/speedup`` so a
14-minute step test takes 42 s at 20x and still samples each lab second
(``--real-sleep`` keeps real time). Figures are drawn but not encoded to
PNG when shown (``--png`` encodes them): a ``Plotter`` or an animated script
shows its figure every period, which made a run CPU-bound. ``!pip`` cells are
not run (counted apart). It prints, per notebook, the cells that pass on the lab and on the
model, and every cell that passes on the model but not on the lab with its
error's last line. The notebooks are not part of the repository: fetch them
to a folder of your own (the TCLab repository's ``notebooks/``, the CBE 30338
course's PID chapters, APMonitor's process-control scripts).

Usage::

    .venv/bin/python benchmarks/bench_tclab_notebooks.py /tmp/nb/tclab
    .venv/bin/python benchmarks/bench_tclab_notebooks.py /tmp/nb/tclab --rig sim:tclab
    .venv/bin/python benchmarks/bench_tclab_notebooks.py /tmp/nb/apm --speedup 20 --json out.json
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import nbformat
from nbclient import NotebookClient
from nbclient.exceptions import CellTimeoutError, DeadKernelError

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_client
from thermolab.rigs.spec import RigSpec


@dataclass
class Outcome:
    """One notebook's cells on one side: passed, and the failures' last error lines."""

    cells: int = 0
    passed: int = 0
    skipped: int = 0
    failures: dict[int, str] = field(default_factory=dict)
    seconds: float = 0.0


def _default_rig() -> str:
    """The kit's two-heater twin ``sim:kit`` where this thermolab has it, else ``sim:tclab``."""
    try:
        RigSpec.parse("sim:kit")
    except ValueError:
        return "sim:tclab"
    return "sim:kit"


@contextlib.contextmanager
def served_lab(speedup: float, rig: str = "sim:kit") -> Iterator[tuple[str, str]]:
    """A lab with the rig ``rig`` at ``speedup`` in a child process: (URL, a teacher's token)."""
    config = (
        "[rig_defaults]\npower_off_grace = 600\ncontrol_time_limit = 3600\n\n"
        f'[[rigs]]\nid = "kit"\ntitle = "TCLab kit\'s twin"\nspec = {json.dumps(rig)}\n'
    )
    with bench_client.served_lab(config, ("--speedup", f"{speedup:g}")) as served:
        yield served


_IMPORTS = [
    (re.compile(r"^(\s*)import tclab\s*$", re.M), r"\1import thermolab.tclab as tclab"),
    (re.compile(r"^(\s*)import tclab as ", re.M), r"\1import thermolab.tclab as "),
    (re.compile(r"^(\s*)from tclab(\.\w+)? import ", re.M), r"\1from thermolab.tclab import "),
]


def _to_lab(source: str) -> str:
    """The only change a notebook needs: its ``tclab`` imports become ``thermolab.tclab``."""
    for pattern, replacement in _IMPORTS:
        source = pattern.sub(replacement, source)
    return source


def _preamble(side: str, speedup: float, real_sleep: bool, png: bool = False) -> str:
    lines = ["import matplotlib", "matplotlib.use('Agg')"]
    if not png:
        # Figures are drawn, but not encoded to PNG on each display: a Plotter or an
        # animated script shows its figure every period, which made a run CPU-bound.
        lines += ["get_ipython().display_formatter.formatters['image/png'].enabled = False"]
    if not real_sleep:
        # The notebook's own time.sleep only: tclab's and thermolab's lab time sleep for real.
        lines += [
            "import sys as _sys, time as _time",
            "_real_sleep = _time.sleep",
            "def _scaled_sleep(seconds):",
            "    caller = _sys._getframe(1).f_globals.get('__name__', '')",
            "    if caller.startswith(('tclab', 'thermolab')):",
            "        return _real_sleep(seconds)",
            f"    return _real_sleep(seconds / {speedup!r})",
            "_time.sleep = _scaled_sleep",
        ]
    if side == "lab":  # lab time as fast as the model's until a TCLab holds the twin's
        lines += ["import thermolab.tclab as _tclab", f"_tclab.labtime.set_rate({speedup!r})"]
    if side == "model":
        lines += [
            "import tclab as _tclab, tclab.experiment as _experiment",
            f"_tclab.labtime.set_rate({speedup!r})",
            "_tclab.TCLab = _tclab.tclab.TCLab = _experiment.TCLab = _tclab.TCLabModel",
            "_setup = _tclab.setup",
            "def _model_setup(connected=True, speedup=1):",
            f"    return _setup(connected=False, speedup={speedup!r} if connected else speedup)",
            "_tclab.setup = _model_setup",
        ]
    return "\n".join(lines)


def _load(path: Path) -> nbformat.NotebookNode:
    if path.suffix == ".py":
        notebook = nbformat.v4.new_notebook()
        notebook.cells = [nbformat.v4.new_code_cell(path.read_text(encoding="utf-8"))]
        return notebook
    return nbformat.read(path, as_version=4)


def run_notebook(
    path: Path, side: str, speedup: float, timeout: float, real_sleep: bool, png: bool = False
) -> Outcome:
    """Run ``path``'s code cells on one side; count those that end without an error."""
    notebook = _load(path)
    outcome = Outcome()
    kept = []
    for cell in notebook.cells:
        if cell.cell_type != "code" or not cell.source.strip():
            continue
        if re.match(r"^\s*[!%]\s*pip\b", cell.source):
            outcome.skipped += 1
            continue
        if side == "lab":
            cell.source = _to_lab(cell.source)
        kept.append(cell)
    outcome.cells = len(kept)
    notebook.cells = [nbformat.v4.new_code_cell(_preamble(side, speedup, real_sleep, png)), *kept]
    started = time.monotonic()
    with tempfile.TemporaryDirectory() as work:
        client = NotebookClient(
            notebook,
            timeout=timeout,
            allow_errors=True,
            interrupt_on_timeout=True,
            kernel_name="python3",
            resources={"metadata": {"path": work}},
        )
        try:
            client.execute()
        except (CellTimeoutError, DeadKernelError, RuntimeError) as exc:
            outcome.failures[-1] = f"{type(exc).__name__}: {str(exc).splitlines()[0]}"
    outcome.seconds = time.monotonic() - started
    for index, cell in enumerate(notebook.cells[1:], start=1):
        errors = [o for o in cell.get("outputs", []) if o.get("output_type") == "error"]
        ran = cell.get("execution_count") is not None
        if ran and not errors:
            outcome.passed += 1
        else:
            last = f"{errors[0]['ename']}: {errors[0]['evalue']}" if errors else "not run"
            outcome.failures[index] = last.splitlines()[0][:240]
    return outcome


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="a folder of *.ipynb notebooks and *.py scripts")
    parser.add_argument(
        "--rig",
        default=_default_rig(),
        metavar="SPEC",
        help="the lab's rig (sim:kit: the kit's two-heater twin; sim:tclab: one heater)",
    )
    parser.add_argument("--speedup", type=float, default=20.0, help="lab time's speed-up (20)")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds a cell may take")
    parser.add_argument("--real-sleep", action="store_true", help="keep time.sleep in real time")
    parser.add_argument(
        "--png", action="store_true", help="encode each figure shown to PNG (off: drawn only)"
    )
    parser.add_argument("--only", help="run the notebooks whose name contains this")
    parser.add_argument("--json", type=Path, help="also write the results here")
    args = parser.parse_args()
    paths = sorted(p for p in args.folder.iterdir() if p.suffix in (".ipynb", ".py"))
    if args.only:
        paths = [p for p in paths if args.only in p.name]
    if not paths:
        raise SystemExit(f"no *.ipynb or *.py in {args.folder}")
    results: dict[str, dict[str, Outcome]] = {}
    RigSpec.parse(args.rig)  # a wrong spec fails here, not in the lab's log
    print(f"lab rig: {args.rig}", flush=True)
    with served_lab(args.speedup, args.rig) as (url, token):
        os.environ.update({"THERMOLAB_URL": url, "THERMOLAB_TOKEN": token, "THERMOLAB_RIG": "kit"})
        for path in paths:
            results[path.name] = {
                side: run_notebook(
                    path, side, args.speedup, args.timeout, args.real_sleep, args.png
                )
                for side in ("model", "lab")
            }
            model, lab = results[path.name]["model"], results[path.name]["lab"]
            print(
                f"{path.name:<70} lab {lab.passed:>2}/{lab.cells:<2}  model "
                f"{model.passed:>2}/{model.cells:<2}  ({lab.seconds:.0f} s, {model.seconds:.0f} s)",
                flush=True,
            )
            for index, error in sorted(lab.failures.items()):
                if index not in model.failures:
                    print(f"    cell {index}: {error}", flush=True)
    lab_total = sum(r["lab"].passed for r in results.values())
    model_total = sum(r["model"].passed for r in results.values())
    cells = sum(r["lab"].cells for r in results.values())
    both = sum(
        len(set(range(1, r["model"].cells + 1)) - set(r["model"].failures) - set(r["lab"].failures))
        for r in results.values()
    )
    print(
        f"\n{len(results)} notebooks, {cells} cells: lab {lab_total}, model {model_total}; "
        f"{both} of the {model_total} cells that pass on the model pass on the lab"
    )
    if args.json:
        args.json.write_text(
            json.dumps({n: {s: asdict(o) for s, o in r.items()} for n, r in results.items()}),
            encoding="utf-8",
        )


if __name__ == "__main__":
    main()
