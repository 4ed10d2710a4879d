"""The lab from a script: :class:`Lab` (rigs, runs, data) and control of a rig (a :class:`Turn`).

A script logs in with a personal API token (created on the user's page in
the lab) instead of a password, sent as ``Authorization: Bearer`` on every
request. Before anything else the client reads ``GET /api/version`` and
refuses a lab whose API it does not speak (:mod:`thermolab.api_version`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import httpx

from thermolab import __version__
from thermolab.api_version import API_VERSION, is_compatible, parse_api_version
from thermolab.client.errors import LabRequestError
from thermolab.client.live import follow_run
from thermolab.client.runs import RunData
from thermolab.client.turn import Turn
from thermolab.errors import IncompatibleLabError, InvalidParameterError

__all__ = ["ENV_TOKEN", "ENV_URL", "Lab", "WaitCallback", "print_place"]

ENV_URL = "THERMOLAB_URL"
ENV_TOKEN = "THERMOLAB_TOKEN"

WaitCallback = Callable[[dict[str, Any]], None]
"""Called with the rig (``GET /api/rigs/{rig}``) whenever the place in the queue changes."""


def print_place(rig: dict[str, Any]) -> None:
    """Say on standard error where the script waits (the default :data:`WaitCallback`)."""
    access = rig["access"]
    wait = access.get("estimatedTimeUntilControl")
    about = f", about {wait:.0f} s" if isinstance(wait, int | float) else ""
    print(
        f"waiting for rig {rig['id']!r}: place {access.get('queuePosition')} of "
        f"{access.get('queueSize')} in the queue{about}",
        file=sys.stderr,
        flush=True,
    )


class Lab:
    """A ThermoLab lab over HTTP.

    Parameters
    ----------
    url : str, optional
        The lab's address (``http://127.0.0.1:8000``); default ``$THERMOLAB_URL``.
    token : str, optional
        A personal API token; default ``$THERMOLAB_TOKEN``.
    timeout : float
        Seconds an HTTP request may take.

    Raises
    ------
    InvalidParameterError
        Without a URL.
    IncompatibleLabError
        If the lab speaks another API version, or is not a ThermoLab lab.
    LabRequestError
        If it cannot be reached.

    Examples
    --------
    ::

        with Lab("http://127.0.0.1:8000", token="tlab_...") as lab:
            print([rig["id"] for rig in lab.rigs()])
            with lab.control("twin") as turn:          # waits in the queue, says its place
                run = turn.start_run(dt=1, samples=600, signal="step:0:5@10", methods=["lsm"])
                for message in lab.follow(run["rig"], run["id"]):
                    ...
            data = lab.run_data(run["id"])             # NumPy arrays; data.to_pandas()
    """

    def __init__(
        self, url: str | None = None, token: str | None = None, *, timeout: float = 10.0
    ) -> None:
        address = url or os.environ.get(ENV_URL)
        if not address:
            raise InvalidParameterError(
                f"no lab address: pass url= or set ${ENV_URL} (such as http://127.0.0.1:8000)"
            )
        self.url = address.rstrip("/")
        self.token = token or os.environ.get(ENV_TOKEN) or None
        headers = {"user-agent": f"thermolab-client/{__version__} (api {API_VERSION})"}
        if self.token:
            headers["authorization"] = f"Bearer {self.token}"
        self._http = httpx.Client(base_url=self.url, headers=headers, timeout=timeout)
        try:
            self.info = self._check_version()
        except BaseException:
            self._http.close()
            raise

    # -- plumbing ---------------------------------------------------------------------------

    def request(self, method: str, path: str, **kwargs: Any) -> Any:
        """Send a request to the lab's API; return the decoded JSON (``None`` for no body).

        Raises
        ------
        LabRequestError
            With the lab's status, code and reason when it refuses.
        """
        try:
            answer = self._http.request(method, path, **kwargs)
        except httpx.HTTPError as exc:
            reason = str(exc) or type(exc).__name__
            raise LabRequestError(method, path, None, "unreachable", reason, url=self.url) from exc
        if answer.status_code >= 400:
            try:
                body = answer.json()
            except ValueError:
                body = {}
            if not isinstance(body, dict):
                body = {}
            detail = str(body.get("detail") or answer.reason_phrase or "refused")
            raise LabRequestError(
                method, path, answer.status_code, str(body.get("code") or "http_error"), detail
            )
        if answer.status_code == 204 or not answer.content:
            return None
        return answer.json()

    def _check_version(self) -> dict[str, Any]:
        try:
            info = self.request("GET", "/api/version")
        except LabRequestError as exc:
            if exc.status in (401, 404):
                raise IncompatibleLabError(
                    f"{self.url} does not publish /api/version: it is not a ThermoLab lab, or "
                    f"one older than API {API_VERSION}"
                ) from None
            raise
        lab_api = info.get("api") if isinstance(info, dict) else None
        try:
            parse_api_version(str(lab_api))
            compatible = is_compatible(str(lab_api))
        except ValueError:
            compatible = False
        if not compatible:
            raise IncompatibleLabError(
                f"the lab at {self.url} speaks API {lab_api} (ThermoLab "
                f"{info.get('version') if isinstance(info, dict) else '?'}); this client speaks "
                f"{API_VERSION} (ThermoLab {__version__}) and needs the same major version with "
                "a minor at least its own: install the client version that matches the lab"
            )
        return dict(info)

    def close(self) -> None:
        """Close the connections (does not release a turn: use :meth:`Turn.release`)."""
        self._http.close()

    def __enter__(self) -> Lab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- reading the lab --------------------------------------------------------------------

    def speedup(self, rig_id: str) -> float | None:
        """How many times faster than real time rig ``rig_id`` runs (its ``speedup``).

        1 for hardware; a twin's is its teacher's setting (``twin_speedup``);
        ``None`` for a twin on a rig host, whose speed-up the lab is not told.
        """
        rig = next((r for r in self.rigs() if r["id"] == rig_id), None)
        if rig is None:
            raise LabRequestError("GET", "/api/rigs", 404, "not_found", f"no rig {rig_id!r}")
        value = rig.get("speedup")
        return None if value is None else float(value)

    def whoami(self) -> dict[str, Any]:
        """The user the token acts as."""
        answer: dict[str, Any] = self.request("GET", "/api/session")
        return answer

    def rigs(self) -> list[dict[str, Any]]:
        """Every rig with its state, input range, limits and access."""
        answer: list[dict[str, Any]] = self.request("GET", "/api/rigs")
        return answer

    def rig(self, rig_id: str) -> dict[str, Any]:
        """One rig (counts as watching it)."""
        answer: dict[str, Any] = self.request("GET", f"/api/rigs/{rig_id}")
        return answer

    def methods(self) -> dict[str, Any]:
        """The identification methods and the settings a run takes (``runSettings``)."""
        answer: dict[str, Any] = self.request("GET", "/api/methods")
        return answer

    def runs(self, *, rig: str | None = None, user: str | None = None) -> list[dict[str, Any]]:
        """Runs (a student's own), newest first."""
        params = {k: v for k, v in (("rig", rig), ("user", user)) if v is not None}
        answer: list[dict[str, Any]] = self.request("GET", "/api/runs", params=params)
        return answer

    def run(self, run_id: int) -> dict[str, Any]:
        """One run: its settings, progress, results and statistics."""
        answer: dict[str, Any] = self.request("GET", f"/api/runs/{run_id}")
        return answer

    def run_data(self, run_id: int) -> RunData:
        """A run's record as NumPy arrays (``.t``, ``.u``, ``.y``, every channel), or pandas."""
        return RunData.from_export(self.request("GET", f"/api/runs/{run_id}/export.json"))

    def follow(
        self, rig_id: str, run_id: int | None = None, *, timeout: float | None = 60.0
    ) -> Iterator[dict[str, Any]]:
        """Yield a run's samples and estimates until it ends (:func:`follow_run`).

        A run that is already over is given from the store: its samples, then
        its ``run`` message (``ended``), so a short run is never missed.
        """
        if run_id is not None:
            run = self.run(run_id)
            if run["status"] != "running":
                return self._replay(run)
        return follow_run(self.url, self.token, rig_id, run_id, timeout=timeout)

    def _replay(self, run: dict[str, Any]) -> Iterator[dict[str, Any]]:
        data = self.run_data(int(run["id"]))
        names = list(data.columns)
        for k in range(len(data)):
            channels = {name: float(data.columns[name][k]) for name in names}
            yield {
                "type": "sample",
                "run": run["id"],
                "k": k,
                "t": channels["t"],
                "u": channels["u"],
                "y": channels["y"],
                "channels": channels,
            }
        yield {"type": "run", "event": "ended", "run": run}

    # -- taking a turn ----------------------------------------------------------------------

    def control(
        self,
        rig_id: str,
        *,
        timeout: float | None = None,
        on_wait: WaitCallback | None = print_place,
        poll: float = 1.0,
    ) -> Turn:
        """Ask for control of a rig and wait in its queue until it is this script's turn.

        Parameters
        ----------
        rig_id : str
        timeout : float, optional
            Seconds to wait in the queue before giving up (the place is left).
        on_wait : callable, optional
            Called with the rig whenever the place in the queue changes
            (default: :func:`print_place`).
        poll : float
            Seconds between looks at the queue (each one keeps the place).

        Raises
        ------
        TimeoutError
            If the turn did not come within ``timeout`` (the queue is left).
        LabRequestError
            If the lab refuses (rig out of service, read-only token...).
        """
        rig = self.request("POST", f"/api/rigs/{rig_id}/control")
        start = time.monotonic()
        shown: tuple[Any, ...] | None = None
        try:
            while rig["access"]["role"] != "controller":
                if rig["access"]["role"] != "queued":
                    raise LabRequestError(
                        "POST",
                        f"/api/rigs/{rig_id}/control",
                        None,
                        "left_queue",
                        "the place in the queue was lost (a teacher removed it, or the rig "
                        "went out of service)",
                    )
                place = (rig["access"]["queuePosition"], rig["access"]["queueSize"])
                if on_wait is not None and place != shown:
                    on_wait(rig)
                shown = place
                if timeout is not None and time.monotonic() - start >= timeout:
                    raise TimeoutError(
                        f"rig {rig_id!r}: no turn within {timeout} s (place {place[0]} of "
                        f"{place[1]}); left the queue"
                    )
                time.sleep(poll)
                rig = self.request("POST", f"/api/rigs/{rig_id}/heartbeat")
        except BaseException:  # Ctrl-C too: never keep a place nobody will use
            self._leave(rig_id)
            raise
        return Turn(self, rig)

    def _leave(self, rig_id: str) -> None:
        # Gone already is fine: the lab ends an unattended place by itself.
        with contextlib.suppress(LabRequestError):
            self.request("DELETE", f"/api/rigs/{rig_id}/control")
