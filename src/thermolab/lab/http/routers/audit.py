"""Routes of the audit log (lab administrators): the rows as JSON, or as CSV."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from thermolab.lab.accounts.policy import Action
from thermolab.lab.audit.log import MAX_ROWS, AuditLog, AuditRecord
from thermolab.lab.http.bodies import Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    USERNAME_PATTERN,
    LabDep,
    SheetDep,
    UserDep,
    documented_errors,
)

__all__ = ["router"]

router = APIRouter(tags=["audit"], **AUTHENTICATED)

ActionQuery = Annotated[
    str | None,
    Query(min_length=1, max_length=48, pattern=r"^[a-z_.]+$", description="only this action"),
]
ActorQuery = Annotated[
    str | None,
    Query(min_length=1, max_length=64, pattern=USERNAME_PATTERN, description="only this actor"),
]
LimitQuery = Annotated[int, Query(ge=1, le=MAX_ROWS, description="at most this many rows")]


class AuditOut(Out):
    """A privileged action: who, what, on what, when, from where."""

    id: int
    at: datetime
    actor: str
    action: str
    target: str
    address: str | None
    detail: dict[str, Any]

    @classmethod
    def of(cls, record: AuditRecord) -> AuditOut:
        """Build from an :class:`~thermolab.lab.audit.log.AuditRecord`."""
        return cls(
            id=record.id,
            at=record.at,
            actor=record.actor,
            action=record.action,
            target=record.target,
            address=record.address,
            detail=dict(record.detail),
        )


@router.get(
    "/audit",
    response_model=list[AuditOut],
    summary="The audit log",
    responses=documented_errors(403, 422),
)
def audit_log(
    who: UserDep,
    lab: LabDep,
    action: ActionQuery = None,
    actor: ActorQuery = None,
    limit: LimitQuery = 500,
) -> list[AuditOut]:
    """Privileged actions, newest first (lab administrators only)."""
    lab.authorize.require_lab(who, Action.AUDIT_READ)
    return [AuditOut.of(r) for r in lab.audit.list(action=action, actor=actor, limit=limit)]


@router.get(
    "/audit.csv",
    summary="The audit log as CSV",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}, **documented_errors(403, 422)},
)
def audit_csv(
    who: UserDep,
    lab: LabDep,
    sheet: SheetDep,
    action: ActionQuery = None,
    actor: ActorQuery = None,
    limit: LimitQuery = MAX_ROWS,
) -> Response:
    """The same rows as CSV, formula-safe (lab administrators only).

    ``?dialect=pt-BR`` (or ``en``, ``es``) and ``tz``: the spreadsheet form.
    """
    lab.authorize.require_lab(who, Action.AUDIT_READ)
    rows = lab.audit.list(action=action, actor=actor, limit=limit)
    return Response(
        AuditLog.to_csv(rows, sheet),
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": 'attachment; filename="thermolab-audit.csv"'},
    )
