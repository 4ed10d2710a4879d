"""A person's own data: ``GET /api/me/export`` (everything the lab holds about the caller)."""

from __future__ import annotations

import json

from fastapi import APIRouter, Response

from thermolab.lab.accounts.personal_data import personal_data
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, UserDep

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


@router.get(
    "/me/export",
    tags=["session"],
    summary="Everything the lab holds about you",
    response_class=Response,
    responses={200: {"content": {"application/json": {}}}},
)
def export_me(who: UserDep, lab: LabDep) -> Response:
    """One JSON file: your account, logins, API tokens (not their secrets), courses,
    turns, queue places, runs with their samples and results, hand-ins and marks,
    bookings you made, LTI identities — every row of every table that is about you.
    """
    document = personal_data(lab.db, who.user_id, who.username)
    body = json.dumps(document, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    return Response(
        body,
        media_type="application/json",
        headers={
            "content-disposition": f'attachment; filename="thermolab-{who.username}.json"',
            "cache-control": "no-store",
        },
    )
