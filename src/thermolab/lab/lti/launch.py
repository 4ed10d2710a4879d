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
   known and the version is 1.3.0, and that every claim the IMS certification
   requires is there (:func:`check_required_claims`: ``roles``, a resource
   link's ``id``, a deep-linking request's settings the tool can honour, a
   ``target_link_uri`` on the tool's own origin). Only then, in one transaction, it marks the
   state used (a replay fails), signs the person in and fills the course.
   Anything refused changes nothing and is logged.
"""

from __future__ import annotations

import hashlib
import logging
import secrets
import threading
from dataclasses import dataclass, field
from datetime import timedelta
from typing import Any
from urllib.parse import urlencode, urlsplit

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
    LtiClaimError,
    LtiInvalidTokenError,
    LtiReplayError,
    LtiStateError,
    LtiTargetError,
    LtiThrottledError,
    LtiUnknownDeploymentError,
    LtiUnknownPlatformError,
)
from thermolab.lab.lti.platforms import PlatformInfo
from thermolab.lab.lti.tokens import JwksCache, unverified_identity, verify_id_token

__all__ = [
    "PRESENTATION_TARGETS",
    "InitiationRate",
    "LaunchOutcome",
    "LoginRedirect",
    "LtiLaunches",
    "check_required_claims",
    "check_target",
]

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


# The content item the tool offers, and the ways it can be shown (Deep Linking 2.0).
_OFFERED_TYPE = "ltiResourceLink"
PRESENTATION_TARGETS = ("iframe", "window")


def check_target(target: object, tool_origin: str) -> str:
    """Refuse a ``target_link_uri`` that is not on the tool's own origin.

    Examples
    --------
    >>> check_target("https://lab.example/api/lti/launch", "https://lab.example/")
    'https://lab.example/api/lti/launch'
    >>> check_target("https://evil.example/api/lti/launch", "https://lab.example/")
    Traceback (most recent call last):
    ...
    thermolab.lab.lti.errors.LtiTargetError: the launch's target_link_uri is not this tool's ...
    """
    if not isinstance(target, str) or not target:
        raise LtiClaimError("the launch has no target_link_uri")
    got, own = urlsplit(target), urlsplit(tool_origin)
    if (got.scheme.lower(), got.netloc.lower()) != (own.scheme.lower(), own.netloc.lower()):
        raise LtiTargetError(
            f"the launch's target_link_uri is not this tool's (it is on "
            f"{got.scheme}://{got.netloc}, the tool is {own.scheme}://{own.netloc})"
        )
    return target


def check_required_claims(claims: dict[str, Any], kind: str, tool_origin: str | None) -> None:
    """Refuse a launch without a claim the IMS certification requires (see the module).

    Raises
    ------
    LtiClaimError
        Naming the claim.
    LtiTargetError
        A ``target_link_uri`` on another origin than ``tool_origin``.
    """
    roles = claims.get(CLAIM["roles"])
    if not isinstance(roles, list) or not all(isinstance(r, str) for r in roles):
        raise LtiClaimError("the launch has no roles claim (a list of role URIs, maybe empty)")
    target = claims.get(CLAIM["target_link_uri"])
    if tool_origin is not None:
        check_target(target, tool_origin)
    elif not isinstance(target, str) or not target:
        raise LtiClaimError("the launch has no target_link_uri")
    if kind == RESOURCE_LINK_REQUEST:
        link = claims.get(CLAIM["resource_link"])
        if not isinstance(link, dict):
            raise LtiClaimError("a resource link launch has no resource_link claim")
        link_id = link.get("id")
        if not isinstance(link_id, str) or not 0 < len(link_id) <= 255:
            raise LtiClaimError("the launch's resource_link has no id (1 to 255 characters)")
        return
    settings = claims.get(CLAIM["dl_settings"])
    if not isinstance(settings, dict):
        raise LtiClaimError("a deep linking request has no deep_linking_settings claim")
    if not isinstance(settings.get("deep_link_return_url"), str):
        raise LtiClaimError("the deep linking settings have no deep_link_return_url")
    accepted = settings.get("accept_types")
    if not isinstance(accepted, list) or _OFFERED_TYPE not in accepted:
        raise LtiClaimError(
            f"the platform accepts {accepted!r}; this tool offers only {_OFFERED_TYPE!r} items"
        )
    targets = settings.get("accept_presentation_document_targets")
    if not isinstance(targets, list) or not set(targets) & set(PRESENTATION_TARGETS):
        raise LtiClaimError(
            f"the platform shows content as {targets!r}; this tool opens in an iframe or a window"
        )
    multiple = settings.get("accept_multiple", True)
    if not isinstance(multiple, bool):
        raise LtiClaimError("the deep linking settings' accept_multiple is not true or false")


class InitiationRate:
    """At most ``per_address`` login initiations per address in ``window`` (a sliding count).

    Each initiation stores a state row, so an anonymous flood would fill the
    table; past the limit the address is refused (HTTP 429) until its oldest
    initiation leaves the window. Addresses are forgotten when idle. This is
    one process's count; workers on a Redis broker count lab-wide
    (:class:`~thermolab.lab.fleet.shared_limits.SharedInitiationRate`, same rule).
    """

    def __init__(
        self, clock: LabClock, *, per_address: int = 30, window: timedelta = timedelta(minutes=1)
    ) -> None:
        self.clock = clock
        self.per_address = per_address
        self.window = window
        self._seen: dict[str, list[float]] = {}
        self._lock = threading.Lock()

    def refusal(self, address: str) -> LtiThrottledError:
        """The error of one initiation too many from ``address``."""
        return LtiThrottledError(
            f"too many LTI logins from {address}: at most {self.per_address} per "
            f"{int(self.window.total_seconds())} s"
        )

    def check(self, address: str) -> None:
        """Count one initiation from ``address``.

        Raises
        ------
        LtiThrottledError
            Past the limit.
        """
        now = self.clock.now().timestamp()
        start = now - self.window.total_seconds()
        with self._lock:
            if len(self._seen) > 10_000:  # forget idle addresses
                self._seen = {a: t for a, t in self._seen.items() if t and t[-1] > start}
            times = [t for t in self._seen.get(address, []) if t > start]
            if len(times) >= self.per_address:
                self._seen[address] = times
                raise self.refusal(address)
            times.append(now)
            self._seen[address] = times


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
        self.initiations = InitiationRate(clock)

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
        tool_origin: str | None = None,
    ) -> LoginRedirect:
        """Start a login: store a state and nonce, return the platform's authorisation URL.

        ``tool_origin``: the tool's own origin, which ``target_link_uri`` must be on.

        Raises
        ------
        LtiUnknownPlatformError
        LtiTargetError
        """
        if tool_origin is not None:
            check_target(target_link_uri, tool_origin)
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

    def complete(
        self,
        id_token: str,
        state: str,
        browser_state: str | None,
        *,
        tool_origin: str | None = None,
    ) -> LaunchOutcome:
        """Check a launch and sign its person in (see the module's notes).

        ``tool_origin``: the tool's own origin, which ``target_link_uri`` must be on.

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
        check_required_claims(claims, str(kind), tool_origin)
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
                add_member(session, course.id, user, person.course_role, now)
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
