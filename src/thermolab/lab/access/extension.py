"""A controller asks for more time: the rules of extending one's own turn.

WCAG 2.2.1 (Timing Adjustable) asks that a person warned of a time limit can
extend it, unless the limit is essential; a rig shared by a queue is exactly
such a case, so the student may extend only while **nobody waits**:

* the queue is empty;
* the turn ends within ``EXTEND_WINDOW`` (60 s: when the page warns);
* each extension adds ``TURN_EXTENSION`` (120 s) to the deadline, and the
  deadline never passes the turn's start + the rig's time limit +
  ``MAX_TURN_EXTENSIONS`` × ``TURN_EXTENSION`` — two extensions per turn, with
  no counter to keep, since the bound is read from the turn itself (a
  teacher's extension uses the same room). A **script's** turn (asked for
  with a personal API token) has no such bound: a 20-minute step test on a
  kit must not be cut while nobody waits, and a script gone silent still
  loses the turn at the client timeout.

A teacher moves the limit freely (``POST .../control/extend``). The rules are
pure functions of the turn, so the access service applies them inside the rig's
locked transaction and the rendered view says whether the controller may
extend now (``canExtend``).
"""

from __future__ import annotations

from datetime import datetime, timedelta

__all__ = [
    "EXTEND_WINDOW",
    "MAX_TURN_EXTENSIONS",
    "TURN_EXTENSION",
    "extension_refusal",
]

TURN_EXTENSION = 120.0
MAX_TURN_EXTENSIONS = 2
EXTEND_WINDOW = 60.0


def extension_refusal(
    *,
    queue_size: int,
    started_at: datetime,
    deadline: datetime,
    time_limit: float,
    now: datetime,
    script: bool = False,
) -> str | None:
    """Why the controller may not extend the turn now; ``None`` if they may.

    ``script``: the turn was asked for with an API token (no ceiling).

    Examples
    --------
    >>> from datetime import UTC, datetime, timedelta
    >>> t0 = datetime(2026, 1, 1, tzinfo=UTC)
    >>> end = t0 + timedelta(seconds=300)
    >>> extension_refusal(queue_size=0, started_at=t0, deadline=end, time_limit=300,
    ...                   now=end - timedelta(seconds=30)) is None
    True
    >>> extension_refusal(queue_size=1, started_at=t0, deadline=end, time_limit=300,
    ...                   now=end - timedelta(seconds=30))
    'someone is waiting for the rig; the turn cannot be extended'
    """
    if queue_size > 0:
        return "someone is waiting for the rig; the turn cannot be extended"
    left = (deadline - now).total_seconds()
    if left > EXTEND_WINDOW:
        return (
            f"the turn can be extended in its last {EXTEND_WINDOW:g} s only ({left:.0f} s are left)"
        )
    if script:
        return None
    ceiling = started_at + timedelta(seconds=time_limit + MAX_TURN_EXTENSIONS * TURN_EXTENSION)
    if deadline + timedelta(seconds=TURN_EXTENSION) > ceiling + timedelta(seconds=1e-3):
        return (
            f"the turn was already extended as far as allowed ({MAX_TURN_EXTENSIONS} times "
            f"{TURN_EXTENSION:g} s)"
        )
    return None
