"""Checking a platform's ``id_token``: signature against its JWKS, then the claims.

The platform's key set is fetched over HTTP with PyJWT's
:class:`jwt.PyJWKClient` and cached per JWKS URL (``lifespan`` seconds); a
``kid`` not in the cached set makes it fetch the set again once (at most
every ``cooldown`` seconds), so a platform's key rotation works without a
restart. Only RS256 is accepted (LTI 1.3 Security Framework), so a
token cannot pick ``none`` or an HMAC "signed" with the public key.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import jwt

from thermolab.lab.lti.claims import CLAIM
from thermolab.lab.lti.errors import LtiInvalidTokenError, LtiJwksUnreachableError
from thermolab.lab.lti.platforms import PlatformInfo

__all__ = ["LEEWAY", "JwksCache", "unverified_identity", "verify_id_token"]

log = logging.getLogger(__name__)

# Seconds of clock difference allowed between the platform and the lab (exp, iat, nbf).
LEEWAY = 60
_MAX_TOKEN = 64 * 1024


class JwksCache:
    """One :class:`jwt.PyJWKClient` per JWKS URL, each caching its key set.

    Parameters
    ----------
    lifespan : float
        Seconds a fetched key set is trusted before it is fetched again.
    timeout : float
        Seconds an HTTP fetch of a key set may take.
    cooldown : float
        Seconds after a fetch before an unknown ``kid`` may force another
        (so that made-up kids cannot make the lab hammer a platform).
    """

    def __init__(
        self, *, lifespan: float = 300.0, timeout: float = 5.0, cooldown: float = 10.0
    ) -> None:
        self._lifespan = lifespan
        self._timeout = timeout
        self.cooldown = cooldown
        self._clients: dict[str, jwt.PyJWKClient] = {}
        self._lock = threading.Lock()

    def key(self, jwks_url: str, token: str) -> Any:
        """The platform key that signed ``token`` (by its ``kid``).

        Raises
        ------
        LtiJwksUnreachableError
            The key set could not be fetched or read.
        LtiInvalidTokenError
            No key of the set has the token's ``kid``.
        """
        with self._lock:
            client = self._clients.get(jwks_url)
            if client is None:
                client = jwt.PyJWKClient(
                    jwks_url,
                    cache_keys=True,
                    lifespan=int(self._lifespan),
                    timeout=int(self._timeout),
                    cooldown_duration=self.cooldown,
                )
                self._clients[jwks_url] = client
        try:
            return client.get_signing_key_from_jwt(token).key
        except jwt.PyJWKClientConnectionError as exc:
            raise LtiJwksUnreachableError(
                f"the platform's key set at {jwks_url} could not be fetched: {exc}"
            ) from None
        except jwt.PyJWKClientError as exc:
            if "Unable to find a signing key" in str(exc):
                raise LtiInvalidTokenError(
                    "no key of the platform's key set signed this id_token (unknown kid)"
                ) from None
            raise LtiJwksUnreachableError(
                f"the platform's key set at {jwks_url} could not be read: {exc}"
            ) from None
        except jwt.DecodeError as exc:
            raise LtiInvalidTokenError(f"the id_token is not a JWT: {exc}") from None


def unverified_identity(token: str) -> tuple[str, list[str]]:
    """The issuer and audiences a token claims, read before its signature is checked.

    They only choose which registered platform's keys check it.

    Raises
    ------
    LtiInvalidTokenError
    """
    if len(token) > _MAX_TOKEN:
        raise LtiInvalidTokenError("the id_token is too long")
    try:
        claims = jwt.decode(token, options={"verify_signature": False})
    except jwt.PyJWTError as exc:
        raise LtiInvalidTokenError(f"the id_token is not a JWT: {exc}") from None
    issuer = claims.get("iss")
    audience = claims.get("aud")
    audiences = [audience] if isinstance(audience, str) else audience
    if not isinstance(issuer, str) or not isinstance(audiences, list) or not audiences:
        raise LtiInvalidTokenError("the id_token has no issuer (iss) or audience (aud)")
    return issuer, [str(a) for a in audiences]


def verify_id_token(token: str, platform: PlatformInfo, keys: JwksCache) -> dict[str, Any]:
    """The claims of a platform's ``id_token`` once its signature and times are checked.

    Checks: RS256 signature by a key of the platform's JWKS; ``iss`` is the
    platform; ``aud`` holds the tool's client id (and ``azp`` is it when there
    are several audiences); ``exp`` and ``iat`` within :data:`LEEWAY`; a
    ``nonce`` and a ``sub`` or a deployment id are present. The caller checks
    the nonce against the login state and the deployment id against the registry.

    Raises
    ------
    LtiInvalidTokenError
    LtiJwksUnreachableError
    """
    key = keys.key(platform.jwks_url, token)
    try:
        claims: dict[str, Any] = jwt.decode(
            token,
            key,
            algorithms=["RS256"],
            audience=platform.client_id,
            issuer=platform.issuer,
            leeway=LEEWAY,
            options={"require": ["exp", "iat", "iss", "aud", "nonce"]},
        )
    except jwt.ExpiredSignatureError:
        raise LtiInvalidTokenError("the id_token has expired") from None
    except jwt.InvalidAudienceError:
        raise LtiInvalidTokenError(
            f"the id_token is not for this tool (audience is not {platform.client_id!r})"
        ) from None
    except jwt.InvalidSignatureError:
        raise LtiInvalidTokenError(
            "the id_token's signature does not match the platform's key"
        ) from None
    except jwt.PyJWTError as exc:
        raise LtiInvalidTokenError(f"the id_token is not valid: {exc}") from None
    audience = claims["aud"]
    if isinstance(audience, list) and len(audience) > 1 and claims.get("azp") != platform.client_id:
        raise LtiInvalidTokenError("the id_token has several audiences but azp is not this tool")
    if not isinstance(claims.get(CLAIM["deployment_id"]), str):
        raise LtiInvalidTokenError("the id_token has no deployment id")
    return claims
