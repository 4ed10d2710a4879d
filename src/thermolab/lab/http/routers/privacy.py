"""The privacy page's one fact from the server: ``GET /api/privacy``, the retention period.

The page is for people deciding whether to log in at all, so it answers
without one; it says nothing about any person.
"""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter
from pydantic import Field

from thermolab.lab.http.bodies import Out
from thermolab.lab.http.deps import LabDep

__all__ = ["router"]

router = APIRouter()


class PrivacyOut(Out):
    """How long the lab keeps people of closed courses, as its operator set it."""

    retention_months: int | None = Field(
        description="students whose courses all closed over this many months ago are removed "
        "automatically (daily); null: nobody is removed automatically"
    )
    retention_action: Literal["pseudonymise", "delete"] = Field(
        description="pseudonymise: their runs stay under a pseudonym; delete: they go too"
    )


@router.get(
    "/privacy",
    response_model=PrivacyOut,
    tags=["session"],
    summary="How long the lab keeps personal data",
)
def privacy(lab: LabDep) -> PrivacyOut:
    """The retention period the privacy page shows (needs no login)."""
    policy = lab.retention.policy
    return PrivacyOut(retention_months=policy.months, retention_action=policy.action)
