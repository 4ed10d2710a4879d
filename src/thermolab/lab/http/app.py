"""The lab's web application: :func:`create_app`.

The app serves the JSON API under ``/api`` (documented at ``/openapi.json``
and ``/docs``) and, when given a folder, the browser interface at ``/``. It
does not import :mod:`thermolab.web`: ``thermolab serve`` hands the folder in.

Every 4xx answer is JSON with a ``detail`` sentence naming the problem. The
lab's exceptions map to status codes as follows: not logged in or wrong
password 401, not allowed 403, unknown rig/user/path 404, clash with the
current state 409, bad value 422, too many logins 429 (with Retry-After);
a body over the configured size is refused with 413 before it is read in full.
State-changing requests from another origin are refused with 403
(:mod:`~thermolab.lab.http.browser_guard`, which also adds the security
headers); the API docs come from the package (:mod:`~thermolab.lab.http.api_docs`).
``X-Forwarded-For`` is believed only from ``access.trusted_proxies``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from pathlib import Path

import anyio.to_thread
from fastapi import FastAPI, WebSocket
from fastapi.staticfiles import StaticFiles
from uvicorn.middleware.proxy_headers import ProxyHeadersMiddleware

from thermolab import __version__
from thermolab.agent.protocol import AGENT_LINK_PATH
from thermolab.lab.config import LabConfig
from thermolab.lab.fleet.workers import Fleet, FollowerLab
from thermolab.lab.http.api_docs import install_api_docs
from thermolab.lab.http.browser_guard import BrowserGuard
from thermolab.lab.http.errors import install_error_handlers
from thermolab.lab.http.forward import (
    ForwardToOwner,
    hold_agent_link,
    owner_tls,
    refuse_agent_link,
)
from thermolab.lab.http.limits import BodyLimit
from thermolab.lab.http.live_socket import LiveEndpoint
from thermolab.lab.http.observe import install_observability
from thermolab.lab.http.outage import install_outage_handler
from thermolab.lab.http.routers import api_router
from thermolab.lab.http.routers.guide_images import CACHEABLE_PREFIX, UPLOAD_ALLOWANCE
from thermolab.lab.http.routers.lti import LTI_CROSS_SITE_PATHS, too_large_page
from thermolab.lab.rigs.opener import device_opener
from thermolab.lab.service import Lab

__all__ = ["RETENTION_INTERVAL", "create_app"]

log = logging.getLogger(__name__)

RETENTION_INTERVAL = 24 * 3600.0
"""Seconds between the server's passes of the retention period (daily)."""


def create_app(
    config: LabConfig,
    static_dir: Path | None = None,
    *,
    lab: Lab | None = None,
    close_lab: bool | None = None,
    sweep_interval: float | None = 1.0,
    fleet: Fleet | None = None,
    retention_interval: float | None = RETENTION_INTERVAL,
    owner_ca: str | None = None,
) -> FastAPI:
    """Build the lab's ASGI application.

    Parameters
    ----------
    config : LabConfig
        The lab's configuration.
    static_dir : Path, optional
        Folder of the browser interface, served at ``/``.
    lab : Lab, optional
        A lab built by the caller (tests inject a clock, a cheap password
        hasher, rig drivers); by default one is built from ``config``, with the
        rigs opened by :func:`thermolab.rigs.open_rig`. The app starts it
        (migrations, safe state) when it starts.
    close_lab : bool, optional
        Close the lab when the app shuts down (runs aborted, rigs safe);
        default: only a lab the app built itself. ``thermolab serve`` passes
        ``True``: uvicorn re-raises SIGTERM after its shutdown, so nothing
        after ``uvicorn.run`` would run.
    fleet : Fleet, optional
        This worker's part in a fleet of workers on one bus (``--broker``): the
        owner relays its live stream; a follower also forwards rig and run
        requests to the owner (:mod:`~thermolab.lab.fleet.workers`).
    owner_ca : str, optional
        A CA file a follower trusts, besides the system's, for an owner served
        over HTTPS (``thermolab serve --ca``; :func:`~thermolab.lab.http.forward.owner_tls`).
    sweep_interval : float or None
        Seconds between sweeps of the access limits in the background;
        ``None`` for none (tests sweep by hand).
    retention_interval : float or None
        Seconds between passes of the retention period (at the start, then
        daily), when the configuration sets one
        (:mod:`~thermolab.lab.classes.retention`); ``None`` for none.

    Returns
    -------
    FastAPI

    Examples
    --------
    >>> import tempfile
    >>> from thermolab.lab.config import default_config
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     app = create_app(default_config(Path(tmp)))
    >>> "/api/rigs/{rig_id}/control" in app.openapi()["paths"]
    True
    """
    owned = lab is None if close_lab is None else close_lab
    the_lab = lab if lab is not None else Lab(config, opener=device_opener())
    live = LiveEndpoint(the_lab, sockets=None if fleet is None else fleet.live_sockets)
    the_lab.add_listener(live)
    if fleet is not None:
        # Other workers hear of access changes from the owner (a standby once promoted).
        the_lab.add_listener(fleet)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        report = await anyio.to_thread.run_sync(the_lab.start)
        app.state.startup = report
        live.bind(asyncio.get_running_loop())
        if fleet is not None:
            fleet.join(live.hub, live.access_changed, the_lab)
        sweeper = (
            asyncio.create_task(_sweep_forever(the_lab, sweep_interval))
            if sweep_interval is not None
            else None
        )
        retainer = (
            asyncio.create_task(_retain_forever(the_lab, retention_interval))
            if retention_interval is not None and the_lab.retention.policy.enabled
            else None
        )
        try:
            yield
        finally:
            live.bind(None)
            for task in (sweeper, retainer):
                if task is not None:
                    task.cancel()
                    with contextlib.suppress(asyncio.CancelledError):
                        await task
            if fleet is not None:
                await anyio.to_thread.run_sync(fleet.close)
            if owned:
                await anyio.to_thread.run_sync(the_lab.close)

    app = FastAPI(
        title=config.title,
        version=__version__,
        description=(
            "ThermoLab remote laboratory: watch rigs, take turns controlling them, "
            "identify the model of a temperature control system. Log in with "
            "POST /api/session; every other route needs the session cookie."
        ),
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
    )
    app.state.lab = the_lab
    app.state.live = live
    app.include_router(api_router)
    install_observability(app, the_lab, live, fleet)  # /healthz, /readyz, /metrics (before "/")
    app.add_api_websocket_route("/api/rigs/{rig_id}/live", live.endpoint, name="live")

    # Rig hosts dial in here (thermolab agent; docs/operator.md, "Rigs on their own computers").
    # A follower sends them on to the owner (docs/fleet.md, "Rig hosts"); a standby holds
    # them while no owner is heard (a takeover), and serves them once it owns.
    async def agent_link(ws: WebSocket) -> None:
        if fleet is None or fleet.role != "follower":
            await the_lab.agents.endpoint(ws)
        elif not (isinstance(the_lab, FollowerLab) and the_lab.standby):
            await refuse_agent_link(ws)
        elif (
            hello := await hold_agent_link(
                ws, owns=lambda: fleet.role != "follower", announcements=lambda: fleet.announcements
            )
        ) is not None:
            await the_lab.agents.endpoint(ws, accepted=True, hello=hello)

    app.add_api_websocket_route(AGENT_LINK_PATH, agent_link, name="agent_link")
    install_error_handlers(app)
    app.state.database_outage = install_outage_handler(app)  # 503, logged once per outage
    install_api_docs(app)
    if static_dir is not None:
        app.mount("/", StaticFiles(directory=static_dir, html=True), name="web")
    app.add_middleware(
        BodyLimit,
        max_bytes=config.access.max_body_bytes,
        allowances=[UPLOAD_ALLOWANCE],
        pages=dict.fromkeys(LTI_CROSS_SITE_PATHS, too_large_page),
    )
    app.add_middleware(
        BrowserGuard,
        frame_ancestors=config.access.frame_ancestors,
        more_ancestors=the_lab.lti.platforms.frame_origins,
        cross_site_paths=LTI_CROSS_SITE_PATHS,
        cacheable_prefixes=[CACHEABLE_PREFIX],
    )
    if fleet is not None and fleet.role == "follower":
        app.add_middleware(
            ForwardToOwner,
            owner_url=lambda: fleet.owner_url,
            here=lambda: fleet.role != "follower",
            on_owner=fleet.on_owner,
            tls=owner_tls(owner_ca),
        )
    if config.access.trusted_proxies:
        # Outermost, so that the guard and the routes see the client's address and scheme.
        app.add_middleware(
            ProxyHeadersMiddleware, trusted_hosts=list(config.access.trusted_proxies)
        )
    return app


async def _sweep_forever(lab: Lab, interval: float) -> None:
    while True:
        await asyncio.sleep(interval)
        try:
            await anyio.to_thread.run_sync(lab.sweep)
        except Exception:  # a failed sweep must not stop the next ones
            log.exception("sweep of the access limits failed")


async def _retain_forever(lab: Lab, interval: float) -> None:
    """Remove the people past the retention period: at the start, then every ``interval``."""
    while True:
        try:
            report = await anyio.to_thread.run_sync(lab.retention.apply)
        except Exception:  # the next pass tries again; a failed one must not stop them
            log.exception("retention pass failed")
        else:
            if report.removed:
                lab.names.forget()
                log.info(
                    "retention: removed %d people of courses closed over %s months ago",
                    len(report.removed),
                    lab.retention.policy.months,
                )
            for reason in report.skipped.values():
                log.info("retention: left one person until the next pass: %s", reason)
        await asyncio.sleep(interval)
