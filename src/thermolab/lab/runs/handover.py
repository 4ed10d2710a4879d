"""What a START needs to know about turns to answer a lost race precisely.

A START that arrives during the caller's turn and finds, at its transaction,
that the turn has ended (released, kicked, out of service, time limit...) lost
a race: it gets 409 ``turn_ended`` naming how the turn ended, not the 403 of
someone who never had the controls.
"""

from __future__ import annotations

from sqlalchemy import select

from thermolab.errors import TurnEndedError
from thermolab.lab.db import Database
from thermolab.lab.db.models import ControlSession

__all__ = ["caller_turn", "turn_ended_error"]


def caller_turn(db: Database, rig_id: str, user_id: int) -> int | None:
    """The id of the caller's live turn at the rig, if they have the controls now."""
    with db.read() as session:
        turn: int | None = session.scalar(
            select(ControlSession.id).where(
                ControlSession.rig_id == rig_id,
                ControlSession.user_id == user_id,
                ControlSession.ended_at.is_(None),
            )
        )
    return turn


def turn_ended_error(db: Database, rig_id: str, turn: int) -> TurnEndedError:
    """The 409 of a START whose turn ``turn`` ended while it was being decided."""
    with db.read() as session:
        reason = session.scalar(select(ControlSession.end_reason).where(ControlSession.id == turn))
    how = f" ({reason})" if reason else ""
    return TurnEndedError(
        f"your turn at the controls of rig {rig_id!r} ended{how} while this START was being "
        "decided; no run was started"
    )
