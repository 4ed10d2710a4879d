"""Rig hosts (``thermolab agent``): ``GET /api/agents``, the status of every remote rig's host.

Teachers only (403 otherwise): last contact, version, what the host drives,
its fault, and the rig as the host last reported it. The link itself is the
WebSocket ``/api/agents/link`` (:mod:`thermolab.lab.agents.hub`).
"""

from __future__ import annotations

from datetime import datetime

from fastapi import APIRouter

from thermolab.lab.http.bodies import Out
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, UserDep, documented_errors

__all__ = ["AgentHostOut", "router"]

router = APIRouter(**AUTHENTICATED)


class AgentHostOut(Out):
    """A rig host as the lab last heard from it."""

    rig: str
    online: bool
    last_contact: datetime | None
    version: str | None
    spec: str | None
    fault: str | None
    powered: bool
    u: float | None
    y: float | None
    pending: int


@router.get(
    "/agents",
    response_model=list[AgentHostOut],
    tags=["rigs"],
    summary="Rig hosts",
    responses=documented_errors(403),
)
def agent_hosts(who: UserDep, lab: LabDep) -> list[AgentHostOut]:
    """Every remote rig's host: online, last contact, version, faults (teachers only)."""
    who.require_teacher("see the rig hosts")
    return [AgentHostOut.model_validate(s.to_dict()) for s in lab.agents.statuses()]
