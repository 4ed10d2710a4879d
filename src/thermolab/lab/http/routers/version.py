"""The lab's version: ``GET /api/version``, the one route a client reads before logging in."""

from __future__ import annotations

from fastapi import APIRouter

from thermolab import __version__
from thermolab.api_version import API_VERSION
from thermolab.lab.http.deps import LabDep
from thermolab.lab.http.script_schemas import LabVersionOut

__all__ = ["router"]

router = APIRouter()


@router.get("/version", response_model=LabVersionOut, tags=["session"], summary="The lab's version")
def lab_version(lab: LabDep) -> LabVersionOut:
    """The package and API versions (clients check ``api``: same major, minor at least
    theirs). Needs no login. Each twin's speed-up is its rig's (``GET /api/rigs``).
    """
    return LabVersionOut(
        name="thermolab",
        title=lab.config.title,
        version=__version__,
        api=API_VERSION,
    )
