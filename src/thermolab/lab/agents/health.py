"""A rig host's health as the lab judges it: its status line and what is wrong with it.

:class:`~thermolab.lab.agents.hub.AgentHub` keeps a :class:`HostStatus` per
remote rig from what its host says, and its monitor (``AgentHub.check``, once
a sweep) asks :func:`host_problem` about each. A rig whose host has been away
(not connected, or linked and silent) for longer than its ``grace``, reports
a fault, or reads outside its safe range gets a fault that starts with
:data:`HEALTH_FAULT` — control ends and none is granted (the access model's
rule for a faulted rig), the teachers' page shows it, an e-mail goes out
where SMTP is configured (:mod:`.notify`) — and the fault clears by itself
when the host is healthy again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

__all__ = ["HEALTH_FAULT", "HostStatus", "host_problem"]

HEALTH_FAULT = "rig host: "
"""How the monitor's faults begin (they clear by themselves; others wait for a teacher)."""


@dataclass
class HostStatus:
    """A rig host as the lab sees it (the status page's line)."""

    rig: str
    online: bool = False
    last_contact: datetime | None = None
    version: str | None = None
    spec: str | None = None
    fault: str | None = None
    powered: bool = False
    u: float | None = None
    y: float | None = None
    pending: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        y = self.y if self.y is None or math.isfinite(self.y) else None
        return {
            "rig": self.rig,
            "online": self.online,
            "lastContact": None if self.last_contact is None else self.last_contact.isoformat(),
            "version": self.version,
            "spec": self.spec,
            "fault": self.fault,
            "powered": self.powered,
            "u": self.u,
            "y": y,
            "pending": self.pending,
        }


def host_problem(
    status: HostStatus,
    now: datetime,
    *,
    linked: bool,
    grace: float,
    limit: float | None,
    expected_until: datetime | None,
) -> str | None:
    """What is wrong with a rig host now, in words (``None``: healthy).

    ``linked``: its link is up now; ``grace``: the seconds it may be away;
    ``limit``: its rig's output limit (the safe range); ``expected_until``:
    hosts not linked yet are given until then to dial in (after a takeover).
    """
    if not linked:
        expected = expected_until
        if expected is not None and now < expected:
            return None
        # A host redialling (a Wi-Fi blip, a cut cable, a lab worker restarted): offline
        # at once, but out of service — which ends the turn — only once it has been away
        # for the grace its run has on the host, counted from its last message. The host
        # keeps its rig safe meanwhile (an idle rig off, a run within its grace).
        heard = status.last_contact
        if heard is not None and now - heard <= timedelta(seconds=grace):
            return None
        return "offline (not connected)"
    if status.last_contact is not None and now - status.last_contact > timedelta(seconds=grace):
        return f"stopped answering (silent for over {grace:g} s)"
    if status.fault is not None:
        return f"reports a fault: {status.fault}"
    if status.y is not None and (
        not math.isfinite(status.y) or (limit is not None and status.y > limit)
    ):
        return f"reading {status.y:g} is outside the rig's safe range (limit {limit})"
    return None
