"""Watching a lab: ``/healthz``, ``/readyz`` and ``/metrics`` (the Prometheus text format).

* ``GET /healthz`` — the process answers (no database, no rig): a liveness probe.
* ``GET /readyz`` — the database answers a round trip, and the broker when the
  lab has one; 503 otherwise. The rigs are listed (in service or not), but a
  rig out of service does not make the lab unready: its other rigs and its
  pages still serve.
* ``GET /metrics`` — requests and their latency by route template (never by
  the path itself, so ``/api/runs/17`` and ``/api/runs/18`` are one series),
  live sockets and watchers per rig, waiting places per rig, runs by status,
  ended turns by reason, each rig's service, fault and power, rig hosts
  online, the database's (and broker's) round trip, and the process's own
  figures (CPU, memory, open files) from ``prometheus_client``. The lab's
  figures are read when scraped, from the database and memory; nothing is
  counted twice across a restart.

Who may read ``/metrics``: a client on loopback (a Prometheus or an exporter
on the same machine, or behind a reverse proxy listed in
``access.trusted_proxies`` only when the real client is on loopback), or one
sending ``Authorization: Bearer TOKEN`` with the token the server was given
(``THERMOLAB_METRICS_TOKEN``). Everyone else gets 403: the figures name the
rigs and tell when a class is in the lab. ``/healthz`` and ``/readyz`` are open
(load balancers probe them) and say nothing but what is up.

Why ``prometheus_client``: the exposition format, its escaping and histogram
buckets are its job, and its parser is what the tests read the page with.
"""

from __future__ import annotations

import hmac
import ipaddress
import os
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from fastapi import APIRouter, FastAPI, Request
from fastapi.responses import JSONResponse, Response
from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Histogram,
    PlatformCollector,
    ProcessCollector,
    generate_latest,
)
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector
from sqlalchemy import func, select, text
from starlette.routing import compile_path
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from thermolab import __version__
from thermolab.lab.db.models import ControlSession, QueueEntry, RigRow, Run

if TYPE_CHECKING:
    from thermolab.lab.fleet.workers import Fleet
    from thermolab.lab.http.live_socket import LiveEndpoint
    from thermolab.lab.service import Lab

__all__ = ["METRICS_TOKEN_VARIABLE", "install_observability"]

METRICS_TOKEN_VARIABLE = "THERMOLAB_METRICS_TOKEN"
"""The environment variable whose value, sent as a bearer token, opens ``/metrics``."""

# Seconds: from a quick JSON answer to a slow export (a run's samples as CSV).
_LATENCY_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)
_UNMATCHED = "(unmatched)"  # static files and unknown paths: one series, not one per path

router = APIRouter(tags=["operations"], include_in_schema=False)  # probes, not the API


@router.get("/healthz", summary="The process is alive")
def healthz() -> dict[str, str]:
    """Always 200 while the server answers; checks nothing else."""
    return {"status": "alive"}


@router.get("/readyz", summary="The lab can serve: database, broker, rigs")
def readyz(request: Request) -> JSONResponse:
    """200 when the database (and the broker, if any) answer; 503 otherwise."""
    lab: Lab = request.app.state.lab
    fleet: Fleet | None = request.app.state.fleet
    checks: dict[str, Any] = {}
    ready = True
    try:
        checks["database"] = {"ok": True, "seconds": round(_database_round_trip(lab), 6)}
    except Exception as exc:  # any failure to reach it is the answer
        checks["database"] = {"ok": False, "error": type(exc).__name__}
        ready = False
    if fleet is not None and fleet.bus.shared:
        try:
            checks["broker"] = {"ok": True, "seconds": round(_broker_round_trip(fleet), 6)}
        except Exception as exc:
            checks["broker"] = {"ok": False, "error": type(exc).__name__}
            ready = False
    if checks["database"]["ok"]:
        checks["rigs"] = {
            rig.id: "in_service" if rig.in_service and rig.fault is None else "out_of_service"
            for rig in _rig_rows(lab)
        }
    body = {"status": "ready" if ready else "unready", "checks": checks}
    return JSONResponse(body, status_code=200 if ready else 503)


@router.get("/metrics", summary="The lab's figures in the Prometheus text format")
def metrics(request: Request) -> Response:
    """The figures, for a client on loopback or one with the metrics token (403 otherwise)."""
    if not _may_read_metrics(request):
        return JSONResponse(
            {
                "code": "forbidden",
                "detail": "/metrics is open on loopback or with the metrics token "
                f"(Authorization: Bearer, ${METRICS_TOKEN_VARIABLE})",
            },
            status_code=403,
        )
    registry: CollectorRegistry = request.app.state.metrics
    return Response(generate_latest(registry), media_type=CONTENT_TYPE_LATEST)


def install_observability(
    app: FastAPI,
    lab: Lab,
    live: LiveEndpoint,
    fleet: Fleet | None = None,
    *,
    metrics_token: str | None = None,
) -> None:
    """Add the three routes and the request timer to ``app``.

    Parameters
    ----------
    app : FastAPI
    lab : Lab
    live : LiveEndpoint
        The live stream whose sockets are counted.
    fleet : Fleet, optional
        The workers' bus, whose broker ``/readyz`` checks.
    metrics_token : str, optional
        Opens ``/metrics`` to a client off loopback; default
        ``$THERMOLAB_METRICS_TOKEN`` (none: loopback only).
    """
    registry = CollectorRegistry(auto_describe=True)
    requests = Counter(
        "thermolab_http_requests",
        "HTTP requests answered, by method, route template and status",
        ["method", "route", "status"],
        registry=registry,
    )
    latency = Histogram(
        "thermolab_http_request_duration_seconds",
        "Time to answer an HTTP request, by method and route template",
        ["method", "route"],
        buckets=_LATENCY_BUCKETS,
        registry=registry,
    )
    registry.register(_LabCollector(lab, live, fleet))
    ProcessCollector(registry=registry)
    PlatformCollector(registry=registry)
    app.state.metrics = registry
    app.state.fleet = fleet
    token = metrics_token if metrics_token is not None else os.environ.get(METRICS_TOKEN_VARIABLE)
    app.state.metrics_token = token or None
    app.include_router(router)
    app.add_middleware(_RequestTimer, requests=requests, latency=latency)


class _RequestTimer:
    """Counts and times each HTTP request under its route's template (pure ASGI).

    The route a request reached is in the scope; its full template (with the
    prefixes of the routers it was included through, which some FastAPI
    versions leave out of the route's own ``path``) is worked out once per
    route from the first request's path.
    """

    def __init__(
        self,
        app: ASGIApp,
        *,
        requests: Counter,
        latency: Histogram,
    ) -> None:
        self.app = app
        self.requests = requests
        self.latency = latency
        self._templates: dict[int, str] = {}

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        status = 500

        async def sending(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, sending)
        finally:
            route = self._template(scope)
            method = scope.get("method", "GET")
            self.requests.labels(method, route, str(status)).inc()
            self.latency.labels(method, route).observe(time.perf_counter() - started)

    def _template(self, scope: Scope) -> str:
        route = scope.get("route")
        suffix = getattr(route, "path", None)
        if route is None or not suffix:
            return _UNMATCHED
        known = self._templates.get(id(route))  # routes live as long as the app
        if known is None:
            # The routers' prefixes are plain text: the template is the part of the
            # path before where the route's own pattern matches, then the pattern.
            path: str = scope.get("path", "")
            regex = compile_path(suffix)[0]
            starts = [i for i, c in enumerate(path) if c == "/"]
            prefix = next((path[:i] for i in starts if regex.match(path[i:])), "")
            known = prefix + suffix
            self._templates[id(route)] = known
        return known


class _LabCollector(Collector):
    """The lab's figures, read when scraped."""

    def __init__(self, lab: Lab, live: LiveEndpoint, fleet: Fleet | None) -> None:
        self.lab = lab
        self.live = live
        self.fleet = fleet

    def describe(self) -> list[Any]:
        return []  # read at each scrape: nothing to check at registration

    def collect(self) -> Iterator[Any]:
        lab = self.lab
        rig_ids = [rig.id for rig in lab.config.rigs]
        info = GaugeMetricFamily("thermolab_info", "ThermoLab's version", labels=["version"])
        info.add_metric([__version__], 1)
        yield info

        sockets = GaugeMetricFamily(
            "thermolab_live_sockets", "Live WebSockets open on this worker", labels=["rig"]
        )
        backlog = GaugeMetricFamily(
            "thermolab_live_queued_messages",
            "Live messages waiting in the rig's clients' queues on this worker",
            labels=["rig"],
        )
        watchers = GaugeMetricFamily(
            "thermolab_watchers", "People watching a rig (lab-wide)", labels=["rig"]
        )
        for rig_id in rig_ids:
            channel = self.live.hub.channels.get(rig_id)
            clients = channel.clients() if channel is not None else []
            sockets.add_metric([rig_id], len(clients))
            backlog.add_metric([rig_id], sum(client.queued for client in clients))
            watchers.add_metric([rig_id], lab.presence.count(rig_id))
        yield sockets
        yield backlog
        yield watchers

        up = GaugeMetricFamily("thermolab_database_up", "1 when the database answered the scrape")
        try:
            round_trip = _database_round_trip(lab)
            yield from self._database_figures(rig_ids)
        except Exception:
            up.add_metric([], 0)
            yield up
        else:
            up.add_metric([], 1)
            yield up
            yield GaugeMetricFamily(
                "thermolab_database_round_trip_seconds",
                "Time of one SELECT 1 to the database",
                value=round_trip,
            )

        hosts = GaugeMetricFamily(
            "thermolab_rig_host_online", "1 when a rig's host is linked to the lab", labels=["rig"]
        )
        for status in lab.agents.statuses():
            hosts.add_metric([status.rig], 1 if status.online else 0)
        yield hosts

        if self.fleet is not None and self.fleet.bus.shared:
            broker = GaugeMetricFamily(
                "thermolab_broker_round_trip_seconds",
                "Time of one PING to the workers' broker (-1: no answer)",
            )
            try:
                broker.add_metric([], _broker_round_trip(self.fleet))
            except Exception:
                broker.add_metric([], -1)
            yield broker

        load = GaugeMetricFamily(
            "thermolab_host_load1", "The machine's load average over one minute"
        )
        load.add_metric([], os.getloadavg()[0])
        yield load

    def _database_figures(self, rig_ids: list[str]) -> Iterator[Any]:
        lab = self.lab
        with lab.db.read() as session:
            rigs = list(session.scalars(select(RigRow)))
            waiting = dict(
                session.execute(
                    select(QueueEntry.rig_id, func.count())
                    .where(QueueEntry.left_at.is_(None))
                    .group_by(QueueEntry.rig_id)
                ).all()
            )
            controlled = dict(
                session.execute(
                    select(ControlSession.rig_id, func.count())
                    .where(ControlSession.ended_at.is_(None))
                    .group_by(ControlSession.rig_id)
                ).all()
            )
            runs = session.execute(
                select(Run.rig_id, Run.status, func.count()).group_by(Run.rig_id, Run.status)
            ).all()
            turns = session.execute(
                select(ControlSession.end_reason, func.count())
                .where(ControlSession.end_reason.is_not(None))
                .group_by(ControlSession.end_reason)
            ).all()
        queue = GaugeMetricFamily(
            "thermolab_queue_waiting", "People waiting for a rig's controls", labels=["rig"]
        )
        busy = GaugeMetricFamily(
            "thermolab_rig_controlled", "1 when someone has a rig's controls", labels=["rig"]
        )
        for rig_id in rig_ids:
            queue.add_metric([rig_id], waiting.get(rig_id, 0))
            busy.add_metric([rig_id], controlled.get(rig_id, 0))
        yield queue
        yield busy
        in_service = GaugeMetricFamily(
            "thermolab_rig_in_service",
            "1 when a rig is in service and has no fault (0: out of service)",
            labels=["rig"],
        )
        faulted = GaugeMetricFamily(
            "thermolab_rig_fault", "1 when a rig reports a fault", labels=["rig"]
        )
        powered = GaugeMetricFamily(
            "thermolab_rig_powered", "1 when a rig's power is on (cooling counts)", labels=["rig"]
        )
        for row in rigs:
            if row.id not in rig_ids:
                continue  # a rig the configuration no longer declares
            in_service.add_metric([row.id], 1 if row.in_service and row.fault is None else 0)
            faulted.add_metric([row.id], 0 if row.fault is None else 1)
            powered.add_metric([row.id], 0 if row.power_state == "off" else 1)
        yield in_service
        yield faulted
        yield powered
        by_status = CounterMetricFamily(
            "thermolab_runs",
            "Runs stored, by rig and status (running, finished, stopped, interrupted, failed)",
            labels=["rig", "status"],
        )
        for rig_id, status, count in runs:
            by_status.add_metric([rig_id, status], count)
        yield by_status
        ended = CounterMetricFamily(
            "thermolab_turns_ended",
            "Turns at the controls ended, by reason (released, time_limit, idle, ...)",
            labels=["reason"],
        )
        for reason, count in turns:
            ended.add_metric([str(reason)], count)
        yield ended


def _database_round_trip(lab: Lab) -> float:
    started = time.perf_counter()
    with lab.db.read() as session:
        session.execute(text("SELECT 1"))
    return time.perf_counter() - started


def _broker_round_trip(fleet: Fleet) -> float:
    started = time.perf_counter()
    fleet.bus.ping()
    return time.perf_counter() - started


def _rig_rows(lab: Lab) -> list[RigRow]:
    declared = {rig.id for rig in lab.config.rigs}
    with lab.db.read() as session:
        return [row for row in session.scalars(select(RigRow)) if row.id in declared]


def _may_read_metrics(request: Request) -> bool:
    token: str | None = request.app.state.metrics_token
    given = request.headers.get("authorization", "")
    if token and given.startswith("Bearer "):
        return hmac.compare_digest(given.removeprefix("Bearer ").encode(), token.encode())
    host = request.client.host if request.client is not None else ""
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
