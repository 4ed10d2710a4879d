"""Helpers shared by every test folder."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest

Poll = Callable[..., bool]


def poll_until(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Wait in real time for something another thread does; return whether it happened.

    For threads that run on their own (a watchdog, a serial emulator, a
    server): simulated time does not pass while this waits, and the condition
    is checked once more at the deadline, so a slow machine only makes the
    wait longer, never the answer different.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return condition()


@pytest.fixture
def wait_until() -> Poll:
    """:func:`poll_until`: ``assert wait_until(lambda: ..., timeout=5.0)``."""
    return poll_until
