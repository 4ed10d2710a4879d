"""What each page of a browser test did, kept for the report of a failure.

A failure seen once in a full CI run cannot be rerun, and by the time pytest
reports it the test's ``finally`` has closed its contexts: the pages are gone.
So every context the session's browser makes keeps a diary of its pages, from
their first event to their close:

- the main frame's addresses (a route the app moved to on its own shows here);
- answers of 400 and over, and requests that failed (a refused read leaves a
  page half drawn);
- console errors and uncaught exceptions;
- the page's text just before its context closed.

The diary is emptied as each test starts; the report hook prints it under the
failure (``tests/web/conftest.py``).
"""

from __future__ import annotations

import contextlib
import time
from typing import Any
from urllib.parse import urlsplit

__all__ = ["DIARY", "keep_diary", "start_diary"]

#: (seconds since the test started, page number, what happened), in order.
DIARY: list[tuple[float, int, str]] = []
_started = [time.monotonic()]
_pages = [0]


def start_diary() -> None:
    """Empty the diary for a new test."""
    DIARY.clear()
    _started[0] = time.monotonic()
    _pages[0] = 0


def _note(number: int, what: str) -> None:
    DIARY.append((time.monotonic() - _started[0], number, what))


def _path(url: str) -> str:
    parts = urlsplit(url)
    return (
        parts.path
        + (f"?{parts.query}" if parts.query else "")
        + (f"#{parts.fragment}" if parts.fragment else "")
    )


def _watch(page: Any) -> None:
    _pages[0] += 1
    number = _pages[0]
    page._thermolab_diary_number = number  # the page's name in the diary
    _note(number, "opened")

    def navigated(frame: Any) -> None:
        if frame == page.main_frame:
            _note(number, f"at {_path(frame.url)}")

    def answered(response: Any) -> None:
        if response.status >= 400:
            _note(number, f"{response.status} {response.request.method} {_path(response.url)}")

    def failed(request: Any) -> None:
        _note(number, f"failed {request.method} {_path(request.url)}: {request.failure}")

    def console(message: Any) -> None:
        # A failed load is already in the diary as its answer.
        if message.type == "error" and not message.text.startswith("Failed to load resource"):
            _note(number, f"console error: {message.text[:300]}")

    page.on("framenavigated", navigated)
    page.on("response", answered)
    page.on("requestfailed", failed)
    page.on("console", console)
    page.on("pageerror", lambda exc: _note(number, f"uncaught: {str(exc)[:300]}"))


def keep_diary(context: Any) -> Any:
    """Keep ``context``'s pages in the diary, and their text as it closes."""
    context.on("page", _watch)
    plain_close = context.close

    def close(*args: Any, **kwargs: Any) -> Any:
        for page in context.pages:
            with contextlib.suppress(Exception):
                text = page.evaluate("() => document.body ? document.body.innerText : ''")
                hash_ = page.evaluate("() => location.hash")
                shown = " | ".join(text.split("\n"))[:600]
                _note(getattr(page, "_thermolab_diary_number", 0), f"closing at {hash_}: {shown}")
        return plain_close(*args, **kwargs)

    context.close = close
    return context
