"""Bookings refused: clashes, booked rigs, slot times, quotas.

Issue #10, item 5 (courses' slots) and issue #24, item 7 (students' own bookings).
"""

from __future__ import annotations

from thermolab.errors.base import ConflictError, InvalidParameterError

__all__ = [
    "BookingClashError",
    "BookingQuotaError",
    "BookingSeriesClashError",
    "RigBookedError",
    "SlotReversedError",
    "SlotTimeError",
    "SlotTooLongError",
    "SlotZoneError",
    "TimeZoneError",
]


class BookingClashError(ConflictError):
    """A booking overlaps another on a rig they share; ``slot`` names the other one.

    ``slot`` holds ``id``, ``course``, ``startsAt``, ``endsAt`` (ISO 8601, UTC)
    and the shared ``rigs``, so a page can say which slot is in the way.
    """

    def __init__(self, message: str, slot: dict[str, object]) -> None:
        super().__init__(message)
        self.slot = slot


class RigBookedError(ConflictError):
    """A rig is booked for another course's slot now; ``slot`` holds its start and end."""

    def __init__(self, message: str, slot: dict[str, object]) -> None:
        super().__init__(message)
        self.slot = slot


class SlotTimeError(InvalidParameterError):
    """A slot's times are not a slot: see the subclasses (each has its stable code)."""


class SlotReversedError(SlotTimeError):
    """A slot that ends at or before it starts (start and end swapped, say)."""


class SlotTooLongError(SlotTimeError):
    """A slot longer than a day that was not said to be longer, or longer than the longest."""


class SlotZoneError(SlotTimeError):
    """A slot's time given without its time zone (a naive date and time)."""


class TimeZoneError(InvalidParameterError):
    """A time zone name that is not an IANA zone the lab knows (``Mars/Olympus``, ``GMT+25``)."""


class BookingQuotaError(ConflictError):
    """A student's own booking past their course's weekly quota; ``quota`` says how much is left.

    ``quota`` holds ``minutesPerWeek``, ``usedMinutes`` (in that week, before this
    booking) and ``weekStartsAt`` (ISO 8601, UTC).
    """

    def __init__(self, message: str, quota: dict[str, object]) -> None:
        super().__init__(message)
        self.quota = quota


class BookingSeriesClashError(ConflictError):
    """Occurrences of a weekly series overlap other bookings; ``clashes`` lists each one.

    Each item holds the occurrence's ``startsAt``, ``endsAt`` and the ``slot`` in
    the way (as :class:`BookingClashError`'s). Nothing was booked.
    """

    def __init__(self, message: str, clashes: list[dict[str, object]]) -> None:
        super().__init__(message)
        self.clashes = clashes
