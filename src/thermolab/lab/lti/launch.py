"""The OIDC login and the launch: :class:`LtiLaunches`.

1. **Login initiation** (:meth:`LtiLaunches.begin`). The platform sends the
   browser to ``/api/lti/login`` with ``iss``, ``login_hint``,
   ``target_link_uri`` and maybe ``lti_message_hint`` and ``client_id``. The
   lab makes a random ``state`` and ``nonce``, stores the state's SHA-256, the
   nonce and an expiry (10 minutes) in ``lti_login_states``, puts the state in
   a cookie of this browser, and sends the browser to the platform's
   authorisation URL.
2. **Launch** (:meth:`LtiLaunches.complete`). The platform posts
   ``id_token`` and ``state`` to ``/api/lti/launch``. The lab checks the
   token (:mod:`.tokens`), that the state is one it made, unexpired, unused,
   for this platform and the one in this browser's cookie, that the token's
   nonce is the state's, the deployment id is registered, the message type is
   known and the version is 1.3.0. Only then, in one transaction, it marks the
   state used (a replay fails), signs the person in and fills the course.
   Anything refused changes nothing and is logged.
"""

from __future__ import annotations

import hashlib
import logging
import secrets
from dataclasses import dataclass, field
from datetime import timedelta
from typing import Any
from urllib.parse import urlencode

from argon2 import PasswordHasher
from sqlalchemy import select, update

from thermolab.lab.accounts.users import UserInfo
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import LtiLoginState, LtiPlatform
from thermolab.lab.db.models import Role
from thermolab.lab.lti.accounts import (
    add_member,
    join_course,
    person_of,
    remember_link,
    sign_in_account,
)
from thermolab.lab.lti.claims import (
    CLAIM,
    DEEP_LINKING_REQUEST,
    LTI_VERSION,
    RESOURCE_LINK_REQUEST,
)
from thermolab.lab.lti.errors import (
    LtiInvalidTokenError,
    LtiReplayError,
    LtiStateError,
    LtiUnknownDeploymentError,
    LtiUnknownPlatformError,
)
from thermolab.lab.lti.platforms import PlatformInfo
from thermolab.lab.lti.tokens import JwksCache, unverified_identity, verify_id_token

__all__ = ["LaunchOutcome", "LoginRedirect", "LtiLaunches"]

log = logging.getLogger(__name__)

STATE_LIFETIME = timedelta(minutes=10)


@dataclass(frozen=True, slots=True)
class LoginRedirect:
    """Where a login initiation sends the browser, and the state its cookie keeps."""

    url: str
    state: str


@dataclass(frozen=True, slots=True)
class LaunchOutcome:
    """A valid launch: who is signed in, what they asked for."""

    user: UserInfo
    platform: PlatformInfo
    message_type: str
    course: str | None
    custom: dict[str, Any] = field(default_factory=dict)
    deep_linking: dict[str, Any] | None = None
    deployment_id: str = ""


def _hash(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class LtiLaunches:
    """Login initiations and launches against the registered platforms."""

    def __init__(
        self, db: Database, clock: LabClock, hasher: PasswordHasher, keys: JwksCache
    ) -> None:
        self._db = db
        self._clock = clock
        self._hasher = hasher
        self._keys = keys

    def _platform(self, issuer: str, client_ids: list[str] | None) -> PlatformInfo:
        if len(issuer) > 255 or any(len(c) > 255 for c in client_ids or ()):
            raise LtiUnknownPlatformError(
                "no registered platform has so long an issuer or client id"
            )
        with self._db.read() as session:
            query = select(LtiPlatform).where(LtiPlatform.issuer == issuer)
            if client_ids:
                query = query.where(LtiPlatform.client_id.in_(client_ids))
            rows = list(session.scalars(query.limit(2)))
        if not rows and client_ids:
            with self._db.read() as session:
                known = session.scalar(select(LtiPlatform.id).where(LtiPlatform.issuer == issuer))
            if known is not None:
                raise LtiInvalidTokenError(
                    f"the launch is not for this tool: {issuer!r} registered it under another "
                    f"client id than {', '.join(repr(c) for c in client_ids[:3])}"
                )
        if len(rows) != 1:
            which = "no" if not rows else "more than one"
            raise LtiUnknownPlatformError(
                f"{which} registered platform has issuer {issuer!r}"
                + (f" and client id {client_ids[0]!r}" if client_ids else "")
            )
        return PlatformInfo.of(rows[0])

    def begin(
        self,
        *,
        issuer: str,
        login_hint: str,
        target_link_uri: str,
        redirect_uri: str,
        lti_message_hint: str | None = None,
        client_id: str | None = None,
    ) -> LoginRedirect:
        """Start a login: store a state and nonce, return the platform's authorisation URL.

        Raises
        ------
        LtiUnknownPlatformError
        """
        platform = self._platform(issuer, [client_id] if client_id else None)
        state = secrets.token_urlsafe(32)
        nonce = secrets.token_urlsafe(32)
        now = self._clock.now()
        with self._db.write() as session:
            session.add(
                LtiLoginState(
                    state_hash=_hash(state),
                    nonce=nonce,
                    platform_id=platform.id,
                    expires_at=now + STATE_LIFETIME,
                )
            )
        query = {
            "scope": "openid",
            "response_type": "id_token",
            "response_mode": "form_post",
            "prompt": "none",
            "client_id": platform.client_id,
            "redirect_uri": redirect_uri,
            "login_hint": login_hint,
            "state": state,
            "nonce": nonce,
        }
        if lti_message_hint is not None:
            query["lti_message_hint"] = lti_message_hint
        separator = "&" if "?" in platform.auth_login_url else "?"
        return LoginRedirect(platform.auth_login_url + separator + urlencode(query), state)

    def complete(self, id_token: str, state: str, browser_state: str | None) -> LaunchOutcome:
        """Check a launch and sign its person in (see the module's notes).

        ``browser_state`` is the state cookie this browser sent (``None`` when
        its cookies were blocked: the launch is then bound by the single-use
        server-side state alone, and the caller hands the login over to a new
        window).

        Raises
        ------
        LtiError
            Each kind of refusal its own class and code; nothing is changed.
        """
        issuer, audiences = unverified_identity(id_token)
        platform = self._platform(issuer, audiences)
        claims = verify_id_token(id_token, platform, self._keys)
        if browser_state is not None and not secrets.compare_digest(browser_state, state):
            raise LtiStateError("the launch's state is not the one this browser started with")
        now = self._clock.now()
        with self._db.read() as session:
            row = session.scalar(
                select(LtiLoginState).where(LtiLoginState.state_hash == _hash(state))
            )
            if row is None or row.platform_id != platform.id:
                raise LtiStateError("the launch's state was not made by this lab for this platform")
            if row.used_at is not None:
                raise LtiReplayError("this launch (its state and nonce) was used already")
            if now >= row.expires_at:
                raise LtiStateError("the login took too long: its state has expired")
            if not secrets.compare_digest(str(claims.get("nonce")), row.nonce):
                raise LtiInvalidTokenError("the id_token's nonce is not the login's")
            state_id = row.id
        deployment = str(claims[CLAIM["deployment_id"]])
        if deployment not in platform.deployment_ids:
            raise LtiUnknownDeploymentError(
                f"deployment {deployment!r} of {platform.issuer} is not registered"
            )
        if claims.get(CLAIM["version"]) != LTI_VERSION:
            raise LtiInvalidTokenError(f"the launch is not LTI {LTI_VERSION}")
        kind = claims.get(CLAIM["message_type"])
        if kind not in (RESOURCE_LINK_REQUEST, DEEP_LINKING_REQUEST):
            raise LtiInvalidTokenError(f"unknown LTI message type {kind!r}")
        person = person_of(claims)
        if not 0 < len(person.sub) <= 255 or not person.sub.isprintable():
            raise LtiInvalidTokenError("the launch names no user (sub), or not a printable one")
        if kind == DEEP_LINKING_REQUEST and person.role is not Role.TEACHER:
            raise LtiInvalidTokenError("only an instructor may choose what to link")
        context = claims.get(CLAIM["context"])
        nrps = claims.get(CLAIM["nrps"]) or {}
        ags = claims.get(CLAIM["ags"]) or {}
        services = {
            "memberships_url": nrps.get("context_memberships_url")
            if isinstance(nrps, dict)
            else None,
            "lineitems_url": ags.get("lineitems") if isinstance(ags, dict) else None,
        }
        with self._db.write() as session:
            used = session.execute(
                update(LtiLoginState)
                .where(LtiLoginState.id == state_id, LtiLoginState.used_at.is_(None))
                .values(used_at=now)
            )
            if getattr(used, "rowcount", 1) != 1:
                raise LtiReplayError("this launch (its state and nonce) was used already")
            user = sign_in_account(session, platform.id, person, now, self._hasher)
            remember_link(session, platform.id, claims)
            course_name = None
            if isinstance(context, dict) and context.get("id"):
                course = join_course(session, platform.id, context, services, now)
                add_member(session, course.id, user, person.role, now)
                course_name = course.name
            info = UserInfo.of(user)
        custom = claims.get(CLAIM["custom"])
        settings = claims.get(CLAIM["dl_settings"])
        log.info(
            "LTI launch: %s from %s (deployment %s) as %r",
            kind,
            platform.issuer,
            deployment,
            info.username,
        )
        return LaunchOutcome(
            user=info,
            platform=platform,
            message_type=str(kind),
            course=course_name,
            custom=dict(custom) if isinstance(custom, dict) else {},
            deep_linking=dict(settings) if isinstance(settings, dict) else None,
            deployment_id=deployment,
        )

    def purge_expired(self) -> int:
        """Forget login states past their expiry; return how many."""
        from sqlalchemy import delete

        with self._db.write() as session:
            result = session.execute(
                delete(LtiLoginState).where(LtiLoginState.expires_at <= self._clock.now())
            )
            return int(getattr(result, "rowcount", 0) or 0)
