"""The ``tclab`` package's own test suite against ``thermolab.tclab`` and a lab's kit twin.

Issue #22's second yardstick: the tests of the ``tclab`` package (those of
``jckantor/TCLab``'s ``tests/`` folder; the 1.0.0 source distribution ships
none), each ``tclab`` import turned into ``thermolab.tclab`` as in
``bench_tclab_notebooks.py``, run with pytest against a ``thermolab serve``
started here (the kit's two-heater twin ``sim:kit`` at ``--speedup``), reached
through ``THERMOLAB_URL``/``THERMOLAB_TOKEN``/``THERMOLAB_RIG``. They run in a
scratch copy of the folder, so its files are never changed. It prints the
pytest summary and each failing test's last line: the tests that cannot pass on
a lab rig by design are named in ``docs/notebooks.md``.

The tests are not part of the repository: fetch them (``git clone
https://github.com/jckantor/TCLab``, the measured commit is a975c36) and give
their ``tests`` folder.

Usage::

    .venv/bin/python benchmarks/bench_tclab_suite.py /tmp/TCLab/tests
    .venv/bin/python benchmarks/bench_tclab_suite.py /tmp/TCLab/tests --rig sim:tclab
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_tclab_notebooks import _default_rig, _to_lab, served_lab
from thermolab.rigs.spec import RigSpec


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tests", type=Path, help="the tclab repository's tests/ folder")
    parser.add_argument("--rig", default=_default_rig(), metavar="SPEC", help="the lab's rig")
    parser.add_argument("--speedup", type=float, default=20.0, help="the twin's speed-up (20)")
    args = parser.parse_args()
    files = sorted(args.tests.glob("test_*.py"))
    if not files:
        raise SystemExit(f"no test_*.py in {args.tests}")
    RigSpec.parse(args.rig)  # a wrong spec fails here, not in the lab's log
    with tempfile.TemporaryDirectory() as scratch, served_lab(args.speedup, args.rig) as lab:
        url, token = lab
        for path in files:
            source = path.read_text(encoding="utf-8")
            (Path(scratch) / path.name).write_text(_to_lab(source), encoding="utf-8")
        for other in args.tests.iterdir():  # fixtures and data the tests read
            if other.is_file() and not other.name.startswith("test_"):
                shutil.copy2(other, scratch)
        env = {**os.environ, "THERMOLAB_URL": url, "THERMOLAB_TOKEN": token,
               "THERMOLAB_RIG": "kit"}  # fmt: skip
        print(f"lab rig: {args.rig} at {args.speedup:g}x; {len(files)} files", flush=True)
        # -p no:cacheprovider: nothing written beside the tests; the scratch folder is the
        # rootdir, so the repository's own pytest configuration does not apply.
        command = [
            *(sys.executable, "-m", "pytest", "-q", "-rf", "-p", "no:cacheprovider"),
            *("-p", "no:randomly", "--rootdir", scratch, "-c", os.devnull, scratch),
        ]
        raise SystemExit(subprocess.run(command, env=env, cwd=scratch, check=False).returncode)


if __name__ == "__main__":
    main()
