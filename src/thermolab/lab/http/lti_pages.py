"""The few HTML pages of the LTI launch (the rest of the lab is the browser app).

A launch arrives as a form post from the LMS, so its answers are pages, not
JSON: a refusal (its stable code, the code's sentence in the reader's
language, the precise English reason), the new-window hand-over when the
browser blocked the lab's cookies in the LMS's frame, and the deep-linking
answer that posts itself back to the LMS (``/js/lti-return.js``; the page has
no inline script, its own policy allows the one form target).
"""

from __future__ import annotations

from html import escape
from urllib.parse import urlsplit

from fastapi.responses import HTMLResponse

from thermolab.lab.error_messages import error_message

__all__ = ["error_page", "handover_page", "return_page"]


def _page(language: str, body: str, status: int, csp: str | None = None) -> HTMLResponse:
    html = (
        f'<!doctype html><html lang="{escape(language)}"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        '<title>ThermoLab</title><link rel="stylesheet" href="/css/app.css"></head>'
        f'<body><main id="main" class="lti-page">{body}</main></body></html>'
    )
    headers = {"Content-Language": language, "Cache-Control": "no-store"}
    if csp is not None:
        headers["Content-Security-Policy"] = csp
    return HTMLResponse(html, status_code=status, headers=headers)


def error_page(code: str, detail: str, status: int, language: str) -> HTMLResponse:
    """A refused launch: the code's sentence, the code, the reason."""
    return _page(
        language,
        f'<h1 id="lti-error">{escape(error_message(code, language))}</h1>'
        f'<p><code id="lti-code">{escape(code)}</code></p>'
        f'<p id="lti-detail" lang="en">{escape(detail)}</p>',
        status,
    )


def handover_page(ticket_url: str, language: str) -> HTMLResponse:
    """Cookies blocked in the frame: a link that opens the signed-in lab in a new window."""
    sentence = escape(error_message("lti_cookies_blocked", language))
    return _page(
        language,
        f'<h1 id="lti-blocked">{sentence}</h1>'
        f'<p><a id="lti-new-window" href="{escape(ticket_url)}" target="_blank" '
        f'rel="noopener">ThermoLab ↗</a></p>',
        200,
    )


def return_page(return_url: str, jwt: str, language: str) -> HTMLResponse:
    """The deep-linking answer, posted to the LMS by ``/js/lti-return.js`` (or by hand)."""
    parts = urlsplit(return_url)
    target = f"{parts.scheme}://{parts.netloc}"
    sentence = escape(error_message("lti_returning", language))
    csp = (
        "default-src 'self'; script-src 'self'; style-src 'self'; object-src 'none'; "
        f"base-uri 'self'; form-action {target}; frame-ancestors *"
    )
    return _page(
        language,
        f'<form id="lti-return" method="post" action="{escape(return_url)}">'
        f'<input type="hidden" name="JWT" value="{escape(jwt)}">'
        f'<button type="submit">{sentence}</button></form>'
        '<script type="module" src="/js/lti-return.js"></script>',
        200,
        csp,
    )
