"""The version of the lab's HTTP API, and the rule for whether a client may speak to a lab.

The lab publishes ``{"version": <package>, "api": "MAJOR.MINOR"}`` at
``GET /api/version``. The rule (:func:`is_compatible`): the majors must be
equal (a major bump removes or changes something a client relies on), and the
lab's minor must be at least the client's (a minor bump only adds routes or
fields, which an older client ignores). So a client of API 1.0 speaks to
any 1.x lab, a client of 1.2 refuses a 1.1 lab, and nobody speaks across
majors. A client refuses an incompatible lab with one clear message
(:class:`thermolab.errors.IncompatibleLabError`) before doing anything.
"""

from __future__ import annotations

__all__ = ["API_VERSION", "is_compatible", "parse_api_version"]

API_VERSION = "1.0"
"""Bump the minor for additions; the major for anything a client could trip on."""


def parse_api_version(text: str) -> tuple[int, int]:
    """Return ``(major, minor)`` of ``"MAJOR.MINOR"``.

    Raises
    ------
    ValueError
        For anything else.

    Examples
    --------
    >>> parse_api_version("1.2")
    (1, 2)
    """
    major, sep, minor = str(text).strip().partition(".")
    if not sep or not major.isdigit() or not minor.isdigit():
        raise ValueError(f"an API version is MAJOR.MINOR (such as {API_VERSION!r}); got {text!r}")
    return int(major), int(minor)


def is_compatible(lab: str, client: str = API_VERSION) -> bool:
    """Whether a client of API ``client`` may speak to a lab of API ``lab``.

    Examples
    --------
    >>> is_compatible("1.3", "1.0"), is_compatible("1.0", "1.3"), is_compatible("2.0", "1.0")
    (True, False, False)
    """
    lab_major, lab_minor = parse_api_version(lab)
    client_major, client_minor = parse_api_version(client)
    return lab_major == client_major and lab_minor >= client_minor
