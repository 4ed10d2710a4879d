"""Registered platforms (LMSs): what a teacher enters once, in the browser.

A platform is known by its issuer and client id; its deployment ids say which
installations of the tool in it may launch. URLs must be ``https`` except on
the loopback host (a platform on the same machine, as in the tests).
"""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import urlsplit

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from thermolab.errors import ConflictError, InvalidParameterError, NotFoundError
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import URL_LENGTH, LtiPlatform

__all__ = ["PlatformInfo", "PlatformRegistry", "check_url"]

_LOOPBACK = frozenset({"localhost", "127.0.0.1", "::1"})
MAX_DEPLOYMENTS = 50


@dataclass(frozen=True, slots=True)
class PlatformInfo:
    """A registered platform."""

    id: int
    issuer: str
    client_id: str
    auth_login_url: str
    token_url: str
    jwks_url: str
    deployment_ids: tuple[str, ...]

    @classmethod
    def of(cls, row: LtiPlatform) -> PlatformInfo:
        """The info of a table row."""
        return cls(
            row.id,
            row.issuer,
            row.client_id,
            row.auth_login_url,
            row.token_url,
            row.jwks_url,
            tuple(str(d) for d in row.deployment_ids),
        )


def check_url(url: str, what: str) -> str:
    """Return ``url`` stripped if it is an absolute https URL (http only on loopback).

    Examples
    --------
    >>> check_url(" https://lms.example/auth ", "auth login URL")
    'https://lms.example/auth'
    >>> check_url("http://lms.example/auth", "auth login URL")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: the auth login URL must be an https:// URL ...
    """
    cleaned = url.strip()
    parts = urlsplit(cleaned)
    secure = parts.scheme == "https" or (
        parts.scheme == "http" and (parts.hostname or "") in _LOOPBACK
    )
    if not secure or not parts.hostname or len(cleaned) > URL_LENGTH:
        raise InvalidParameterError(
            f"the {what} must be an https:// URL (http:// only on this machine), not {url!r}"
        )
    return cleaned


def _origin(url: str) -> str:
    parts = urlsplit(url)
    return f"{parts.scheme}://{parts.netloc}"


def _text(value: str, what: str) -> str:
    cleaned = value.strip()
    if not 0 < len(cleaned) <= 255:
        raise InvalidParameterError(f"the {what} must have 1 to 255 characters")
    return cleaned


class PlatformRegistry:
    """Register, list, change and remove platforms."""

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock
        self._origins: tuple[str, ...] | None = None

    def frame_origins(self) -> tuple[str, ...]:
        """The origins of the registered platforms (they may frame the lab), cached."""
        found = self._origins
        if found is None:
            with self._db.read() as session:
                rows = session.execute(select(LtiPlatform.issuer, LtiPlatform.auth_login_url))
                origins = {_origin(url) for row in rows for url in row}
            found = self._origins = tuple(sorted(origins))
        return found

    def register(
        self,
        *,
        issuer: str,
        client_id: str,
        auth_login_url: str,
        token_url: str,
        jwks_url: str,
        deployment_ids: list[str],
    ) -> PlatformInfo:
        """Register a platform.

        Raises
        ------
        InvalidParameterError
            A URL that is not https (http only on loopback), an empty field, no deployment id.
        ConflictError
            The issuer and client id are registered already.
        """
        deployments = sorted({_text(d, "deployment id") for d in deployment_ids})
        if not 0 < len(deployments) <= MAX_DEPLOYMENTS:
            raise InvalidParameterError(
                f"give 1 to {MAX_DEPLOYMENTS} deployment ids (the LMS shows them when the tool "
                "is added)"
            )
        row = LtiPlatform(
            issuer=check_url(issuer, "issuer"),
            client_id=_text(client_id, "client id"),
            auth_login_url=check_url(auth_login_url, "auth login URL"),
            token_url=check_url(token_url, "token URL"),
            jwks_url=check_url(jwks_url, "JWKS URL"),
            deployment_ids=deployments,
            created_at=self._clock.now(),
        )
        try:
            with self._db.write() as session:
                clash = session.scalar(
                    select(LtiPlatform.id).where(
                        LtiPlatform.issuer == row.issuer, LtiPlatform.client_id == row.client_id
                    )
                )
                if clash is not None:
                    raise ConflictError(
                        f"the platform {row.issuer!r} with client id {row.client_id!r} "
                        "is registered already",
                        case="platform_registered",
                    )
                session.add(row)
                session.flush()
                info = PlatformInfo.of(row)
        except IntegrityError:
            raise ConflictError(
                f"the platform {row.issuer!r} is registered already", case="platform_registered"
            ) from None
        self._origins = None
        return info

    def list(self) -> list[PlatformInfo]:
        """Every registered platform, oldest first."""
        with self._db.read() as session:
            return [PlatformInfo.of(p) for p in session.scalars(select(LtiPlatform).order_by("id"))]

    def get(self, platform_id: int) -> PlatformInfo:
        """One platform.

        Raises
        ------
        NotFoundError
        """
        with self._db.read() as session:
            row = session.get(LtiPlatform, platform_id)
            if row is None:
                raise NotFoundError(f"no LTI platform number {platform_id}")
            return PlatformInfo.of(row)

    def remove(self, platform_id: int) -> None:
        """Remove a platform (its identities, states and queued grades go with it).

        Raises
        ------
        NotFoundError
        """
        with self._db.write() as session:
            row = session.get(LtiPlatform, platform_id)
            if row is None:
                raise NotFoundError(f"no LTI platform number {platform_id}")
            session.delete(row)
        self._origins = None
