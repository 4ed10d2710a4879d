"""A slot's times, checked once for every way of booking (issue #24, item 7).

A slot is ``[starts_at, ends_at)``: two instants that carry their time zone
(a naive "13:00" means a different moment in every zone, so it is refused,
``slot_zone_missing``), the end strictly after the start
(``slot_ends_before_start``: the page once added a day to a slot whose times
were swapped and booked 23 hours over midnight without a word), and at most
:data:`MAX_SLOT_HOURS` long unless the teacher says it is longer on purpose
(``longer``), then at most :data:`MAX_LONG_SLOT_DAYS` days (``slot_too_long``).
Each refusal is a 422 with its stable code, worded in the reader's language.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from thermolab.errors import SlotReversedError, SlotTooLongError, SlotZoneError

__all__ = ["MAX_LONG_SLOT_DAYS", "MAX_SLOT_HOURS", "check_slot"]

MAX_SLOT_HOURS = 24
"""The longest slot booked without saying it is longer (a class, not a semester)."""
MAX_LONG_SLOT_DAYS = 7
"""The longest slot a teacher may book when saying it is longer (a week's project)."""


def check_slot(
    starts_at: datetime, ends_at: datetime, *, longer: bool = False
) -> tuple[datetime, datetime]:
    """Return the slot ``[starts_at, ends_at)`` in UTC, or refuse it.

    Parameters
    ----------
    starts_at, ends_at : datetime
        Aware instants (any zone).
    longer : bool
        The teacher said the slot is longer than a day on purpose.

    Raises
    ------
    SlotZoneError
        A time without its zone.
    SlotReversedError
        The end at or before the start.
    SlotTooLongError
        Longer than :data:`MAX_SLOT_HOURS` hours (``longer`` false) or
        :data:`MAX_LONG_SLOT_DAYS` days.

    Examples
    --------
    >>> from datetime import timezone
    >>> brt = timezone(timedelta(hours=-3))
    >>> check_slot(datetime(2026, 3, 2, 10, tzinfo=brt), datetime(2026, 3, 2, 12, tzinfo=brt))[0]
    datetime.datetime(2026, 3, 2, 13, 0, tzinfo=datetime.timezone.utc)
    """
    for name, t in (("starts_at", starts_at), ("ends_at", ends_at)):
        if t.tzinfo is None or t.utcoffset() is None:
            raise SlotZoneError(
                f"{name} must carry a time zone (an ISO 8601 instant such as "
                f"2026-03-02T13:00:00Z), got {t.isoformat()}"
            )
    start, end = starts_at.astimezone(UTC), ends_at.astimezone(UTC)
    if end <= start:
        raise SlotReversedError(
            f"a slot must end after it starts, got {start.isoformat()} to {end.isoformat()} "
            "(are the start and end swapped?)"
        )
    longest = timedelta(days=MAX_LONG_SLOT_DAYS) if longer else timedelta(hours=MAX_SLOT_HOURS)
    if end - start > longest:
        if longer:
            raise SlotTooLongError(f"a slot may last at most {MAX_LONG_SLOT_DAYS} days")
        raise SlotTooLongError(
            f"a slot may last at most {MAX_SLOT_HOURS} hours unless it is said to be longer "
            f"(longer: true, up to {MAX_LONG_SLOT_DAYS} days)"
        )
    return start, end
