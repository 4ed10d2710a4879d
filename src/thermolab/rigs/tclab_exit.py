"""Heaters off when the process ends, for every TCLab kit still open.

The driver registers each kit it opens (:func:`register`) and unregisters it
when it is released (:func:`unregister`). The first registration installs the
hooks, once: ``atexit`` closes every kit still open (normal exit, and after
an unhandled exception); from the main thread, SIGTERM and SIGINT handlers
write the heater-off commands to every open kit at once, without waiting for
locks or replies, then let the process unwind as it would have (the previous
handler, ``KeyboardInterrupt``, or ``SystemExit(128 + signum)``), so ``with``
blocks and ``finally`` clauses still run. SIGKILL cannot be caught (see
:mod:`thermolab.rigs.tclab`).
"""

from __future__ import annotations

import atexit
import signal
import threading
from collections.abc import Callable
from types import FrameType
from typing import Any, Protocol

__all__ = ["OpenKit", "register", "unregister"]


class OpenKit(Protocol):
    """What the hooks need of an open kit (a :class:`~thermolab.rigs.tclab.TCLabRig`)."""

    def close(self) -> None:
        """Switch the heaters off and release the kit (idempotent)."""
        ...

    def _emergency_off(self) -> None:
        """Write heater-off commands without waiting for replies (signal-handler safe)."""
        ...


# Strong references: a kit that was never closed must still be switched off at exit.
_open_rigs: set[OpenKit] = set()
_registry_lock = threading.Lock()
_exit_hooks_installed = False
_SignalHandler = Callable[[int, FrameType | None], Any] | int | None


def register(rig: OpenKit) -> None:
    """Switch ``rig`` off when the process ends (installs the hooks on first use).

    Parameters
    ----------
    rig : OpenKit
        A kit just opened; held by a strong reference until :func:`unregister`.
    """
    global _exit_hooks_installed
    with _registry_lock:
        _open_rigs.add(rig)
        if _exit_hooks_installed:
            return
        _exit_hooks_installed = True
    atexit.register(_close_all)
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGTERM, signal.SIGINT):
            previous: _SignalHandler = signal.getsignal(signum)
            signal.signal(signum, _make_signal_handler(previous))


def unregister(rig: OpenKit) -> None:
    """Forget ``rig`` (released: nothing left to switch off); no effect if unknown."""
    with _registry_lock:
        _open_rigs.discard(rig)


def _close_all() -> None:
    with _registry_lock:
        rigs = list(_open_rigs)
    for rig in rigs:
        rig.close()


def _make_signal_handler(previous: _SignalHandler) -> Callable[[int, FrameType | None], None]:
    def handler(signum: int, frame: FrameType | None) -> None:
        # Heaters off first, without waiting for locks or replies; then unwind as before.
        for rig in list(_open_rigs):
            rig._emergency_off()
        if callable(previous):
            previous(signum, frame)
        elif previous == signal.SIG_IGN:
            return
        elif signum == signal.SIGINT:
            raise KeyboardInterrupt
        else:
            raise SystemExit(128 + signum)

    return handler
