"""Calling the platform: OAuth 2 access tokens, the roster (NRPS) and scores (AGS).

The tool proves who it is with OAuth 2 client credentials and a JWT bearer
assertion (RFC 7523) signed with its own key (:mod:`.keys`), as LTI
Advantage requires; access tokens are cached until shortly before they expire.
HTTP is httpx's (already the lab's client library), with a short timeout.
"""

from __future__ import annotations

import secrets
import threading
import time
from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

from thermolab.lab.clock import LabClock
from thermolab.lab.lti.errors import LtiServiceError
from thermolab.lab.lti.keys import ToolKeys
from thermolab.lab.lti.platforms import PlatformInfo

if TYPE_CHECKING:
    import httpx

__all__ = ["PlatformClient"]

_ASSERTION = "urn:ietf:params:oauth:client-assertion-type:jwt-bearer"
_MEMBERSHIPS = "application/vnd.ims.lti-nrps.v2.membershipcontainer+json"
_SCORE = "application/vnd.ims.lis.v1.score+json"
_MAX_PAGES = 100


class PlatformClient:
    """HTTP calls to platforms on the tool's behalf.

    Parameters
    ----------
    keys : ToolKeys
    clock : LabClock
    timeout : float
        Seconds each HTTP request may take.
    """

    def __init__(self, keys: ToolKeys, clock: LabClock, *, timeout: float = 10.0) -> None:
        self._keys = keys
        self._clock = clock
        self._timeout = timeout
        self._tokens: dict[tuple[int, str], tuple[str, datetime]] = {}
        self._lock = threading.Lock()

    def access_token(self, platform: PlatformInfo, scopes: tuple[str, ...]) -> str:
        """An access token for ``scopes`` from the platform's token URL (cached).

        Raises
        ------
        LtiServiceError
        """
        scope = " ".join(scopes)
        now = self._clock.now()
        with self._lock:
            cached = self._tokens.get((platform.id, scope))
        if cached is not None and cached[1] > now:
            return cached[0]
        moment = int(time.time())  # JWT times are the wall clock's, whatever the lab's clock
        assertion = self._keys.sign(
            {
                "iss": platform.client_id,
                "sub": platform.client_id,
                "aud": platform.token_url,
                "iat": moment,
                "exp": moment + 300,
                "jti": secrets.token_urlsafe(16),
            }
        )
        answer = self._call(
            "POST",
            platform.token_url,
            data={
                "grant_type": "client_credentials",
                "client_assertion_type": _ASSERTION,
                "client_assertion": assertion,
                "scope": scope,
            },
        )
        token = answer.get("access_token")
        if not isinstance(token, str) or not token:
            raise LtiServiceError(f"the token URL {platform.token_url} gave no access_token")
        lifetime = answer.get("expires_in", 3600)
        seconds = float(lifetime) if isinstance(lifetime, int | float) else 3600.0
        with self._lock:
            self._tokens[(platform.id, scope)] = (
                token,
                now + timedelta(seconds=max(0.0, seconds - 60)),
            )
        return token

    def memberships(self, platform: PlatformInfo, url: str, scope: str) -> list[dict[str, Any]]:
        """Every member of an NRPS context membership URL (following ``rel="next"`` pages)."""
        token = self.access_token(platform, (scope,))
        members: list[dict[str, Any]] = []
        next_url: str | None = url
        for _ in range(_MAX_PAGES):
            if next_url is None:
                break
            response = self._raw("GET", next_url, token=token, accept=_MEMBERSHIPS)
            body = _json(response, next_url)
            page = body.get("members")
            if not isinstance(page, list):
                raise LtiServiceError(f"the roster at {next_url} has no list of members")
            members.extend(m for m in page if isinstance(m, dict))
            link = response.links.get("next")
            next_url = link.get("url") if link else None
        return members

    def post_score(
        self,
        platform: PlatformInfo,
        lineitem_url: str,
        score: dict[str, Any],
        scopes: tuple[str, ...],
    ) -> None:
        """POST a score to ``<line item>/scores``.

        Raises
        ------
        LtiServiceError
        """
        token = self.access_token(platform, scopes)
        base, _, query = lineitem_url.partition("?")
        target = base.rstrip("/") + "/scores" + (f"?{query}" if query else "")
        self._raw("POST", target, token=token, json=score, content_type=_SCORE)

    def _call(self, method: str, url: str, **kwargs: Any) -> dict[str, Any]:
        return _json(self._raw(method, url, **kwargs), url)

    def _raw(
        self,
        method: str,
        url: str,
        *,
        token: str | None = None,
        accept: str | None = None,
        content_type: str | None = None,
        **kwargs: Any,
    ) -> httpx.Response:
        headers = {}
        if token is not None:
            headers["Authorization"] = f"Bearer {token}"
        if accept is not None:
            headers["Accept"] = accept
        if content_type is not None:
            headers["Content-Type"] = content_type
        # Imported at the first call: httpx imports its command line's libraries (rich,
        # click) where they are installed, 0.2-0.3 s of every server's start that most
        # labs, with no LMS, never use.
        import httpx

        try:
            response = httpx.request(method, url, headers=headers, timeout=self._timeout, **kwargs)
        except httpx.HTTPError as exc:
            raise LtiServiceError(f"{method} {url} failed: {exc}") from None
        if response.status_code >= 400:
            raise LtiServiceError(
                f"{method} {url} answered HTTP {response.status_code}: {response.text[:200]}"
            )
        return response


def _json(response: httpx.Response, url: str) -> dict[str, Any]:
    try:
        body = response.json()
    except ValueError:
        raise LtiServiceError(f"{url} did not answer JSON") from None
    if not isinstance(body, dict):
        raise LtiServiceError(f"{url} did not answer a JSON object")
    return body
