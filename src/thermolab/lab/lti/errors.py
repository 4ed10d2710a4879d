"""Why an LTI message was refused: one class per stable code (``http/errors.py`` maps them)."""

from __future__ import annotations

from thermolab.errors import ThermoLabError

__all__ = [
    "LtiClaimError",
    "LtiError",
    "LtiFormTooLargeError",
    "LtiInvalidTokenError",
    "LtiJwksUnreachableError",
    "LtiReplayError",
    "LtiServiceError",
    "LtiStateError",
    "LtiTargetError",
    "LtiThrottledError",
    "LtiUnknownDeploymentError",
    "LtiUnknownPlatformError",
]


class LtiError(ThermoLabError):
    """Base class of a refused LTI message (HTTP 400, code ``lti_invalid``)."""


class LtiInvalidTokenError(LtiError):
    """The ``id_token`` is forged, expired, for another audience or lacks a claim."""


class LtiReplayError(LtiError):
    """The login state (and its nonce) was already used: a replayed launch."""


class LtiStateError(LtiError):
    """The state is unknown, expired, or not the one this browser started with."""


class LtiUnknownPlatformError(LtiError):
    """No registered platform has this issuer and client id."""


class LtiUnknownDeploymentError(LtiError):
    """The platform is registered, but not this deployment id."""


class LtiJwksUnreachableError(LtiError):
    """The platform's key set (JWKS) could not be fetched or read."""


class LtiServiceError(LtiError):
    """A platform service (token, roster, scores) failed or answered nonsense."""


class LtiClaimError(LtiError):
    """A required claim of the launch is missing or malformed (roles, resource link...)."""


class LtiTargetError(LtiError):
    """The launch's ``target_link_uri`` is not one of this tool's own URLs."""


class LtiFormTooLargeError(LtiError):
    """The LMS's login or launch form is over the size the tool reads (HTTP 413)."""


class LtiThrottledError(LtiError):
    """Too many login initiations from one address (HTTP 429)."""
