"""The path of a START through the lab service, traced as it runs.

A ``sys.setprofile`` hook records every call made on the request's thread
while the route function ``POST /api/rigs/{rig}/runs`` runs (the cookie check
and the middleware are every request's, not START's), and keeps the calls from
one ``thermolab.lab`` module into another. The test asserts how many lab
modules a START crosses (docs/architecture.md names them; the test prints the
count) and that every such call goes down the import graph: the callee never
imports, directly or not, the module that called it. What goes back up is an
event, through a listener the upper module registered (:data:`EVENT_HOOKS`),
and nothing else.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Iterator
from pathlib import Path

import pytest

from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.http.routers.runs import RunIn, start_run
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory

# On SQLite alone: the calls a START makes, traced in Python (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

#: The modules that do START's work, in the order first entered (docs/architecture.md).
START_PATH = (
    "http.routers.runs",  # the route and its bodies: RunIn.request(), RunOut.of()
    "runs.where",  # RunsByRig: the rig's runs are in this process (not on a rig host)
    "runs.service",  # RunService.start: the previous turn's run, the hub's claim, the runner
    "runs.starting",  # plan_start, then store_start in the turn's transaction
    "rigs.devices",  # the rig's published range and driver, the hub's lock
    "rigs.slot",  # RigSlot: the one rig the hub holds (its levels; claim sets its pace)
    "runs.request",  # plan_run: the one check, the operating point, the identifiers
    "runs.store",  # run_channels, add_run, read
    "access.transactions",  # caller_turn (a lost race is told apart), controlled()
    "db.engine",  # the transactions
    "access.queries",  # their SQL (read_slots: a course's limits during its slot)
    "access.rules",  # current_slot; next_state: the limits applied
    "runs.recorder",  # DatabaseRecorder: the samples' way to the database
)
#: Values every part of the lab reads (the rig's config, the clock, the column
#: types, the watchers a request touches), not steps of START.
LEAVES = frozenset({"config.model", "clock", "db.models", "live.presence"})
#: The listeners the lab registered, told of the change (events going up).
EVENTS = frozenset({"service", "http.live_socket", "live.fanout"})

#: Listeners through which a lower module tells an upper one (events, not calls): the
#: lab's ``on_change`` / ``on_run`` hooks, and the live endpoint as a ``LabListener``.
EVENT_HOOKS = frozenset(
    {
        ("thermolab.lab.service", "Lab._reconcile"),
        ("thermolab.lab.service", "Lab._run_changed"),
        ("thermolab.lab.http.live_socket", "LiveEndpoint.access_changed"),
        ("thermolab.lab.http.live_socket", "LiveEndpoint.run_changed"),
    }
)

LAB = "thermolab.lab."


def _lab_module(frame: types.FrameType) -> str | None:
    name = frame.f_globals.get("__name__", "")
    if not isinstance(name, str) or not name.startswith(LAB):
        return None
    # Generated code (a dataclass's __init__) runs with its class's module name
    # but is no function of that file.
    if not frame.f_code.co_filename.endswith(".py"):
        return None
    return name


def _source_imports(module: str) -> set[str]:
    """The lab modules named by ``module``'s import statements (what it depends on)."""
    path = Path(importlib.import_module(module).__file__ or "")
    found = set()
    for line in path.read_text(encoding="utf-8").splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] in ("from", "import") and words[1].startswith(LAB):
            found.add(words[1])
            # "from thermolab.lab.access import queries as q" imports a module too.
            if words[0] == "from" and len(words) >= 4:
                found.add(f"{words[1]}.{words[3].rstrip(',')}")
    return found


def _reaches(module: str) -> set[str]:
    """Every lab module ``module`` imports, following import statements transitively."""
    seen: set[str] = set()
    todo = [module]
    while todo:
        for name in _source_imports(todo.pop()):
            # "from thermolab.lab.access import x" reaches the package and its modules.
            candidates = [name]
            if hasattr(sys.modules.get(name), "__path__"):
                candidates += _source_imports(name)
            for target in candidates:
                if target not in seen and target in sys.modules:
                    seen.add(target)
                    todo.append(target)
    return seen


@pytest.fixture
def controlled_lab(make_lab: LabFactory) -> Iterator[tuple[Lab, Principal]]:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=VirtualClock())

    lab = make_lab(opener=opener)
    info = lab.users.add("ana", PASSWORD, "student")
    ana = Principal(info.id, info.username, info.role)
    lab.access.request_control("twin", ana)
    yield lab, ana
    lab.runs.wait("twin", 30)


def trace_start(lab: Lab, who: Principal) -> list[tuple[str, str, str]]:
    """Run the START route function under a profiler; return (caller, callee, function)."""
    create_app(lab.config, lab=lab, sweep_interval=None)  # the live stream listens
    body = RunIn.model_validate(
        {"dt": 1.0, "samples": 50, "signal": "step:0:10@10", "methods": ["lsm", "wlsm"]}
    )
    edges: list[tuple[str, str, str]] = []

    def profile(frame: types.FrameType, event: str, arg: object) -> None:
        if event != "call":
            return
        callee = _lab_module(frame)
        caller_frame = frame.f_back
        if callee is None or caller_frame is None:
            return
        # The nearest lab module up the stack is the caller (library frames between
        # them, as SQLAlchemy's event hooks, belong to the call).
        caller = None
        while caller_frame is not None and caller is None:
            caller = _lab_module(caller_frame)
            caller_frame = caller_frame.f_back
        if caller is not None and caller != callee:
            edges.append((caller, callee, frame.f_code.co_qualname))

    sys.setprofile(profile)
    try:
        start_run("twin", body, who, lab)
    finally:
        sys.setprofile(None)
    return edges


def test_a_start_crosses_the_documented_modules_and_only_goes_down(
    controlled_lab: tuple[Lab, Principal],
) -> None:
    lab, ana = controlled_lab
    edges = trace_start(lab, ana)
    crossed: list[str] = []
    for caller, callee, _ in edges:
        for name in (caller, callee):
            short = name.removeprefix(LAB)
            if short not in crossed:
                crossed.append(short)
    path = tuple(name for name in crossed if name not in LEAVES | EVENTS)
    assert path == START_PATH
    assert set(crossed) == set(START_PATH) | LEAVES | EVENTS
    up = [
        (caller, callee, function)
        for caller, callee, function in edges
        if callee not in _reaches(caller) and (callee, function) not in EVENT_HOOKS
    ]
    assert not up, f"calls that climb back up the import graph: {sorted(set(up))}"
    # The figures docs/architecture.md gives (pytest -s shows them).
    print(f"START crosses {len(path)} lab work modules, {len(crossed)} lab modules in all")
    assert lab.runs.list(ana)[0].rig_id == "twin"
