"""Per student of a course: time at the controls, runs, methods and their latest results.

Each function is one set-based query over the whole course (grouped by
user), never a loop over students or a read of samples: a method's result is
read as the few JSON fields the table shows, not its stored trajectories.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import ColumnElement, Select, func, select
from sqlalchemy.orm import Session

from thermolab.lab.analytics.sql import at, clipped_seconds, json_document, seconds
from thermolab.lab.db.models import ControlSession, MethodResultRow, Run

__all__ = ["LatestResult", "control_time", "latest_results", "run_counts", "trusted"]


@dataclass(frozen=True, slots=True)
class LatestResult:
    """A method's result in a student's most recent run that used it."""

    method: str
    runs: int
    run_id: int
    at: datetime
    K: float | None
    tau: float | None
    theta: float | None
    trusted: bool


def control_time(
    session: Session, students: Select[int], start: datetime, end: datetime, now: datetime
) -> dict[int, tuple[int, float]]:
    """``{user_id: (turns, seconds at the controls inside [start, end))}``."""
    until = func.coalesce(ControlSession.ended_at, at("now", now))
    rows = session.execute(
        select(
            ControlSession.user_id,
            func.count(),
            func.sum(clipped_seconds(ControlSession.started_at, until, start, end)),
        )
        .where(
            ControlSession.user_id.in_(students),
            ControlSession.started_at < at("to", end),
            until > at("from", start),
        )
        .group_by(ControlSession.user_id)
    )
    return {user: (int(turns), seconds(total)) for user, turns, total in rows if user is not None}


def run_counts(
    session: Session, students: Select[int], start: datetime, end: datetime
) -> dict[int, dict[str, int]]:
    """``{user_id: {status: runs}}`` of the runs started inside ``[start, end)``."""
    rows = session.execute(
        select(Run.user_id, Run.status, func.count())
        .where(_started_in(start, end), Run.user_id.in_(students))
        .group_by(Run.user_id, Run.status)
    )
    out: dict[int, dict[str, int]] = {}
    for user, status, count in rows:
        out.setdefault(user, {})[status] = int(count)
    return out


def latest_results(
    session: Session, students: Select[int], start: datetime, end: datetime
) -> dict[int, list[LatestResult]]:
    """Per student, each method they used: how many runs, and its newest result.

    The newest result of each (student, method) is chosen on the rows' keys
    alone; only those rows' JSON is then read, and each document is parsed
    once for ``latest`` (PostgreSQL's ``json`` is text, parsed at every
    extraction, and a stored result carries its whole trajectory); the few
    fields of ``latest`` are read from it here.
    """
    per = (Run.user_id, MethodResultRow.method)
    ranked = (
        select(
            MethodResultRow.id.label("result_id"),
            Run.user_id.label("user_id"),
            MethodResultRow.method.label("method"),
            Run.id.label("run_id"),
            Run.started_at.label("started_at"),
            func.count().over(partition_by=per).label("uses"),
            func.row_number()
            .over(partition_by=per, order_by=(Run.started_at.desc(), Run.id.desc()))
            .label("rank"),
        )
        .join(Run, Run.id == MethodResultRow.run_id)
        .where(_started_in(start, end), Run.user_id.in_(students))
        .subquery("ranked")
    )
    docs = (
        select(
            ranked.c.user_id,
            ranked.c.method,
            ranked.c.run_id,
            ranked.c.started_at,
            ranked.c.uses,
            json_document(MethodResultRow.result).label("doc"),
        )
        .join(MethodResultRow, MethodResultRow.id == ranked.c.result_id)
        .where(ranked.c["rank"] == 1)
        .offset(0)  # keeps the subquery: each document is parsed once
        .subquery("docs")
    )
    doc = docs.c.doc
    rows = session.execute(
        select(
            docs.c.user_id,
            docs.c.method,
            docs.c.run_id,
            docs.c.started_at,
            docs.c.uses,
            doc["latest"].label("latest"),
            doc[("stats", "converged")].as_boolean().label("converged"),
            doc["error"].as_string().label("error"),
        ).order_by(docs.c.user_id, docs.c.method)
    ).mappings()
    out: dict[int, list[LatestResult]] = {}
    for row in rows:
        latest: dict[str, Any] = row["latest"] if isinstance(row["latest"], dict) else {}
        extras: dict[str, Any] = latest["extras"] if isinstance(latest.get("extras"), dict) else {}
        out.setdefault(row["user_id"], []).append(
            LatestResult(
                method=row["method"],
                runs=int(row["uses"]),
                run_id=int(row["run_id"]),
                at=row["started_at"],
                K=_finite(latest.get("K")),
                tau=_finite(latest.get("tau")),
                theta=_finite(extras.get("theta")),
                trusted=trusted(
                    {
                        "valid": latest.get("valid"),
                        "K": latest.get("K"),
                        "tau": latest.get("tau"),
                        "flag": extras.get("trusted"),
                        "warnings": extras.get("warnings"),
                        "converged": row["converged"],
                        "error": row["error"],
                    }
                ),
            )
        )
    return out


def trusted(row: Mapping[str, Any]) -> bool:
    """The browser's rule (``results.js``): a valid model that converged, flagged trusted.

    Without the library's own ``trusted`` flag, a result is trusted when it
    has no warning and no error.
    """
    valid = bool(row["valid"]) and _finite(row["K"]) is not None and _finite(row["tau"]) is not None
    if not valid or row["converged"] is False:
        return False
    if row["flag"] is not None:
        return bool(row["flag"])
    return not row["warnings"] and not row["error"]


def _started_in(start: datetime, end: datetime) -> ColumnElement[bool]:
    return (Run.started_at >= at("from", start)) & (Run.started_at < at("to", end))


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    number = float(value)
    return number if number == number and abs(number) != float("inf") else None
