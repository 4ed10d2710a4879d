"""A rig's output on demand: ``GET /api/rigs/{rig}/reading`` (a script's sensor read)."""

from __future__ import annotations

from fastapi import APIRouter

from thermolab.lab.http.deps import AUTHENTICATED, LabDep, RigId, UserDep, documented_errors
from thermolab.lab.http.script_schemas import ReadingOut

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


@router.get(
    "/rigs/{rig_id}/reading",
    response_model=ReadingOut,
    tags=["rigs"],
    summary="The rig's output",
    responses=documented_errors(404),
)
def read_output(rig_id: RigId, who: UserDep, lab: LabDep) -> ReadingOut:
    """The controller's read takes a fresh reading from the device (``fresh``); anyone
    else gets the lab's latest. Counts as the caller's heartbeat for the rig.
    """
    reading = lab.read_output(rig_id, who)
    return ReadingOut.of(reading, lab.hub.published(rig_id).output_unit)
