"""IANA time zones by name: the one check of a zone a person or the configuration gives.

A name is looked up in :func:`zoneinfo.available_timezones`, never opened first:
:class:`~zoneinfo.ZoneInfo` would try any path it is given. Used by the lab's
``time_zone`` (:class:`~thermolab.lab.config.LabConfig`), a weekly series' zone and
the spreadsheet form's ``tz``.
"""

from __future__ import annotations

from datetime import UTC, tzinfo
from functools import cache
from zoneinfo import ZoneInfo, available_timezones

from thermolab.errors import TimeZoneError

__all__ = ["is_known_zone", "zone_named"]


@cache
def _zones() -> frozenset[str]:
    return frozenset(available_timezones())


def is_known_zone(name: str) -> bool:
    """Whether ``name`` is ``UTC`` or an IANA zone of this machine's database.

    >>> is_known_zone("America/Sao_Paulo"), is_known_zone("Mars/Olympus"), is_known_zone("UTC")
    (True, False, True)
    """
    return name == "UTC" or name in _zones()


def zone_named(name: str) -> tzinfo:
    """The time zone called ``name`` (an IANA name such as ``Europe/Lisbon``, or ``UTC``).

    Raises
    ------
    TimeZoneError
        Not a known IANA zone (422 ``time_zone_unknown``).

    Examples
    --------
    >>> zone_named("Europe/Lisbon")
    zoneinfo.ZoneInfo(key='Europe/Lisbon')
    """
    if not is_known_zone(name):
        raise TimeZoneError(f"{name!r} is not a known IANA time zone (like America/Sao_Paulo)")
    return UTC if name == "UTC" else ZoneInfo(name)
