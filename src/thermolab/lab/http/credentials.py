"""Who a request is: a login's cookie, or a personal API token as ``Authorization: Bearer``.

A request that carries an ``Authorization`` header is judged by it alone,
never by a cookie that came along: a bearer request is a script's, so the
browser's same-origin guard does not apply to it (a page on another site
cannot read a token, and the browser never adds one by itself; see
:mod:`~thermolab.lab.http.browser_guard`), and a cross-site page that sends a
made-up header next to the victim's cookie gets 401, not the victim's rights.
"""

from __future__ import annotations

from thermolab.lab.accounts.users import Principal
from thermolab.lab.service import Lab

__all__ = ["BEARER", "bearer_token", "resolve_principal"]

BEARER = "bearer"


def bearer_token(authorization: str | None) -> str | None:
    """The token of an ``Authorization: Bearer <token>`` header (``None`` for other schemes).

    Examples
    --------
    >>> bearer_token("Bearer tlab_abc")
    'tlab_abc'
    >>> bearer_token("Basic dXNlcg==") is None
    True
    """
    if authorization is None:
        return None
    scheme, _, token = authorization.strip().partition(" ")
    if scheme.lower() != BEARER or not token.strip():
        return None
    return token.strip()


def resolve_principal(
    lab: Lab, *, cookie: str | None, authorization: str | None
) -> Principal | None:
    """Return the user behind a request's credentials, or ``None`` (call in a worker thread)."""
    if authorization is not None:
        return lab.tokens.resolve(bearer_token(authorization))
    return lab.sessions.resolve(cookie)
