"""Schemathesis, in its stateful mode, against the real app: no 500, answers as published.

Schemathesis reads ``/openapi.json``, infers the links between operations (a run
started gives the id its reads and exports take; an account created, the name its
removal takes) and drives sequences of calls as a student and as a teacher, on
SQLite and on PostgreSQL. Each answer goes through two checks: "not a server
error" and "response-schema conformance" (the body is what the OpenAPI publishes
for that status). ``KNOWN`` lists the failures it still finds, each with its
reason; anything else fails the test, and a 500 always does.

Each scenario gets a fresh lab on an empty database (a copy of a migrated SQLite
file, or a truncated PostgreSQL schema), so a sequence means the same thing
whenever Hypothesis draws it. The rigs are twins whose clock never moves during
a scenario: a run started stays running, deterministic, until the scenario ends.
Schemathesis adapts what it draws to the answers it saw, which Hypothesis may
report as ``Flaky`` when it replays a prefix; such a run ends there (as in
schemathesis's own engine) and the next seed goes on.

Operations no chain reaches (the login, "who am I", the method registry) then
get cases of their own, valid and invalid. Run with ``-s`` to see the counts
(operations, calls, failures by check).
"""

from __future__ import annotations

import collections
import math
import os
import shutil
from collections.abc import Awaitable, Callable, Iterable, Iterator, MutableMapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import seed as hypothesis_seed
from hypothesis import strategies as st
from hypothesis.errors import Flaky
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.core.failures import Failure, FailureGroup
from schemathesis.specs.openapi.checks import response_schema_conformance

from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.db import Database
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig

from .conftest import FAST_HASHER, PASSWORD, empty_postgres, make_config
from .test_runs import StepClock

Message = MutableMapping[str, Any]
ASGIApp = Callable[
    [Message, Callable[[], Awaitable[Message]], Callable[[Message], Awaitable[None]]],
    Awaitable[None],
]

# Bounded so both databases and both roles take about two minutes of CI's two cores
# together; THERMOLAB_FUZZ_SEEDS=8 (say) draws four times as many sequences.
SEEDS = range(int(os.environ.get("THERMOLAB_FUZZ_SEEDS", "2")))
SCENARIOS_PER_SEED = 12
STEPS_PER_SCENARIO = 8
ALONE_EXAMPLES = 6  # for each operation no chain reached, on SQLite
ALONE_EXAMPLES_POSTGRES = 3  # the same there: what differs is types and constraints
CHECKS = (not_a_server_error, response_schema_conformance)

# (check, operation) -> why it still fails. Empty: schemathesis finds nothing else.
KNOWN: dict[tuple[str, str], str] = {}

USERS = {"student": "ana", "teacher": "tina"}


class CurrentApp:
    """The ASGI app schemathesis calls: the current scenario's, with a crash as a 500.

    The schema is loaded once; each scenario swaps in a new app over a new lab.
    An exception escaping the app becomes the 500 a server would send, so the
    "not a server error" check counts it (Starlette's test transport re-raises).
    """

    def __init__(self) -> None:
        self.app: ASGIApp | None = None

    async def __call__(
        self,
        scope: Message,
        receive: Callable[[], Awaitable[Message]],
        send: Callable[[Message], Awaitable[None]],
    ) -> None:
        assert self.app is not None
        started = False

        async def tracked(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, tracked)
        except Exception as exc:
            if started:  # Starlette already sent its 500 before re-raising
                return
            await send({"type": "http.response.start", "status": 500, "headers": []})
            await send({"type": "http.response.body", "body": repr(exc).encode()})


@dataclass
class Tally:
    """What the runs did: calls per operation, failures per (check, operation)."""

    calls: collections.Counter[str] = field(default_factory=collections.Counter)
    failures: collections.Counter[tuple[str, str]] = field(default_factory=collections.Counter)
    examples: dict[tuple[str, str], str] = field(default_factory=dict)
    flaky_runs: int = 0
    missed: set[str] = field(default_factory=set)

    def checked(self, response: Any, case: Any) -> None:
        """Count a call and run the checks on its answer (failures are tallied, not raised)."""
        operation = f"{case.method} {case.operation.path}"
        self.calls[operation] += 1
        try:
            case.validate_response(response, checks=list(CHECKS))
        except FailureGroup as group:
            for failure in group.exceptions:
                self.failed(failure, operation, response.status_code, response.text)
        except Failure as failure:
            self.failed(failure, operation, response.status_code, response.text)

    def failed(self, failure: Failure, operation: str, status: int, body: str) -> None:
        check = next(iter(type(failure).checks), type(failure).__name__)
        key = (check, operation)
        self.failures[key] += 1
        self.examples.setdefault(key, f"{status}: {failure.title}: {body[:300]}")

    def report(self, label: str) -> str:
        by_check = collections.Counter[str]()
        for (check, _), count in self.failures.items():
            by_check[check] += count
        lines = [
            f"schemathesis stateful, {label}: {len(self.calls)} operations called "
            f"(not: {', '.join(sorted(self.missed)) or 'none'}), "
            f"{sum(self.calls.values())} calls, {self.flaky_runs} runs ended as Flaky, "
            f"failures by check: {dict(by_check) or 'none'}"
        ]
        lines += [f"  {key}: {self.examples[key]}" for key in self.failures]
        return "\n".join(lines)


class FreshLabs:
    """A new lab on an empty database for each scenario, and the app over it."""

    def __init__(self, tmp_path: Path, empty_url: Callable[[], str], role: str) -> None:
        self.tmp_path = tmp_path
        self.empty_url = empty_url
        self.role = role
        self.current = CurrentApp()
        self.lab: Lab | None = None
        self.rig_clock = StepClock()
        self.token = ""

    def open(self) -> None:
        url = self.empty_url()
        rig_clock = self.rig_clock = StepClock()  # frozen: runs stay running

        def opener(rig: RigConfig) -> Rig:
            return TwinRig("paper" if rig.id == "twin" else "tclab", clock=rig_clock)

        lab = Lab(
            make_config(self.tmp_path, url),
            clock=ManualClock(),
            hasher=FAST_HASHER,
            opener=opener,
            database=Database(url, pool_size=2, max_overflow=4),
        )
        lab.start()
        lab.runs.handover_wait = 0.0  # the previous turn's run never ends here: answer at once
        for role, name in USERS.items():
            info = lab.users.add(name, PASSWORD, role)
            if role == self.role:
                self.token, _ = lab.sessions.create(info)
        self.lab = lab
        self.current.app = create_app(lab.config, lab=lab, sweep_interval=None)

    def close(self) -> None:
        self.rig_clock.allow(math.inf)  # let any run reach its abort
        if self.lab is not None:
            self.lab.close()
            self.lab = None


def _rig_ids(
    context: Any, path_parameters: dict[str, Any] | None
) -> st.SearchStrategy[dict[str, Any] | None]:
    # Drawn from the pattern alone a rig id is never a real one: name the lab's rigs too.
    if path_parameters is None or "rig_id" not in path_parameters:
        return st.just(path_parameters)
    real = st.sampled_from(["twin", "other"]).map(lambda rig: {**path_parameters, "rig_id": rig})
    return st.one_of(real, st.just(path_parameters))


def run_stateful(
    labs: FreshLabs, seeds: Iterable[int] = SEEDS, alone_examples: int = ALONE_EXAMPLES
) -> Tally:
    labs.open()
    schema = schemathesis.openapi.from_asgi("/openapi.json", labs.current)
    # Logging out would leave the rest of a scenario at 401.
    schema = schema.exclude(method="DELETE", path="/api/session")
    schema.hook("flatmap_path_parameters")(_rig_ids)
    labs.close()
    tally = Tally()

    class Machine(schema.as_state_machine()):  # type: ignore[misc]
        def setup(self) -> None:
            labs.open()

        def teardown(self) -> None:
            labs.close()

        def get_call_kwargs(self, case: Any) -> dict[str, Any]:
            return {"headers": {"cookie": f"thermolab_session={labs.token}"}}

        def validate_response(
            self, response: Any, case: Any, additional_checks: Any = None, **kwargs: Any
        ) -> None:
            tally.checked(response, case)

        def _repr_step(self, rule: Any, data: Any, result: Any) -> str:
            # Hypothesis 6.170 replays a failing scenario printing each step, and for a
            # rule that raised before returning the result its bundle expects, its
            # printer asserts a name that was never made: that AssertionError ("assert 0
            # >= 1", seen once in a run on PostgreSQL under load) then hides the rule's
            # own error. Print the step without the assignment so the real error shows.
            try:
                return str(super()._repr_step(rule, data, result))
            except AssertionError:
                return f"state.{rule.function.__name__}(...)  # raised"

    for number in seeds:  # a run that ends as Flaky ends early; the next seed goes on
        try:
            hypothesis_seed(number)(Machine).run(
                settings=settings(
                    max_examples=SCENARIOS_PER_SEED,
                    stateful_step_count=STEPS_PER_SCENARIO,
                    deadline=None,
                    database=None,
                    phases=[Phase.generate],
                    suppress_health_check=list(HealthCheck),
                )
            )
        except Flaky:
            tally.flaky_runs += 1
    # The stateful phase calls only what links reach (GET /api/methods, the login and
    # "who am I" are no step of any chain): each operation it left out gets cases of its own.
    operations = {f"{op.method.upper()} {op.path}": op for op in _operations(schema)}
    labs.open()
    try:
        for label in sorted(set(operations) - set(tally.calls)):
            _call_alone(operations[label], labs, tally, alone_examples)
    finally:
        labs.close()
    tally.missed = set(operations) - set(tally.calls)
    return tally


def _call_alone(operation: Any, labs: FreshLabs, tally: Tally, examples: int) -> None:
    strategy = st.one_of(
        operation.as_strategy(GenerationMode.POSITIVE),
        operation.as_strategy(GenerationMode.NEGATIVE),
    )

    @settings(
        max_examples=examples,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(case=strategy)
    def call(case: Any) -> None:
        response = case.call(headers={"cookie": f"thermolab_session={labs.token}"})
        tally.checked(response, case)

    call()


def _operations(schema: Any) -> Iterator[Any]:
    for result in schema.get_all_operations():
        yield result.ok()


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def empty_database(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Callable[[], str]]:
    """A function returning the URL of an empty, migrated database (new for each call)."""
    if request.param == "sqlite":
        template: Path = request.getfixturevalue("migrated_sqlite")
        made = iter(range(1_000_000))

        def sqlite() -> str:
            path = tmp_path / f"lab-{next(made)}.sqlite3"
            shutil.copyfile(template, path)
            return f"sqlite:///{path}"

        yield sqlite
        return
    url: str = request.getfixturevalue("migrated_postgres")

    def postgres() -> str:
        empty_postgres(url)
        return url

    yield postgres


@pytest.mark.slow
@pytest.mark.parametrize("role", list(USERS))
def test_schemathesis_stateful_finds_no_server_error(
    empty_database: Callable[[], str], tmp_path: Path, role: str, request: pytest.FixtureRequest
) -> None:
    labs = FreshLabs(tmp_path, empty_database, role)
    # PostgreSQL draws the first seed's sequences and fewer cases of the operations no
    # chain reaches: what differs there is the database's types, constraints and locks,
    # which those calls all reach; the logic is the same on both, and SQLite explores it
    # with every seed.
    on_sqlite = "sqlite" in request.node.callspec.id
    try:
        if on_sqlite:
            tally = run_stateful(labs)
        else:
            tally = run_stateful(labs, SEEDS[:1], ALONE_EXAMPLES_POSTGRES)
    finally:
        labs.close()
    print("\n" + tally.report(f"{request.node.callspec.id}"))
    assert len(tally.calls) >= 15, tally.calls  # the run reached most of the API
    servers = {key: tally.examples[key] for key in tally.failures if key[0] == "not_a_server_error"}
    assert not servers, servers
    unexpected = {key: tally.examples[key] for key in tally.failures if key not in KNOWN}
    assert not unexpected, unexpected
