"""The layer rule: numerics import no web, database or hardware code."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

NUMERIC_MODULES = [
    "thermolab.control",
    "thermolab.ident",
    "thermolab.signals",
    "thermolab.simulation",
    "thermolab.reproduction",
    "thermolab.records",
]
FORBIDDEN_PREFIXES = [
    "fastapi",
    "starlette",
    "sqlalchemy",
    "alembic",
    "serial",
    "uvicorn",
    "websockets",
    "thermolab.rigs",
    "thermolab.runner",
    "thermolab.lab",
    "thermolab.web",
]


def test_numerics_import_no_web_database_or_hardware_code() -> None:
    # A fresh interpreter, so that modules other tests imported cannot hide a leak.
    code = textwrap.dedent(
        f"""
        import importlib, json, sys
        for name in {NUMERIC_MODULES!r}:
            try:
                importlib.import_module(name)
            except ModuleNotFoundError as exc:
                if exc.name != name:  # a missing layer is fine, a missing dependency is not
                    raise
        forbidden = {FORBIDDEN_PREFIXES!r}
        print(json.dumps(sorted(
            m for m in sys.modules if any(m == f or m.startswith(f + ".") for f in forbidden)
        )))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


def test_the_clients_import_no_server_database_or_device_code() -> None:
    code = textwrap.dedent(
        """
        import json, sys
        import thermolab.client, thermolab.tclab
        forbidden = ["fastapi", "starlette", "sqlalchemy", "alembic", "serial", "uvicorn",
                     "thermolab.lab", "thermolab.web", "thermolab.cli", "thermolab.runner",
                     "thermolab.rigs"]
        print(json.dumps(sorted(
            m for m in sys.modules if any(m == f or m.startswith(f + ".") for f in forbidden)
        )))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


def test_a_lab_and_a_rig_host_start_without_scipy() -> None:
    # SciPy's signal and optimize packages cost 0.8 s at import; the lab's and the host's
    # processes import them when a run first needs them, not at start.
    code = textwrap.dedent(
        """
        import json, sys
        import thermolab.lab.http.app, thermolab.agent.host, thermolab.cli.serve
        print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] == "scipy")))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []
