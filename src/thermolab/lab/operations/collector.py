"""The cyclic garbage collector's full passes kept short while the live stream runs.

CPython 3.11 collects reference cycles in generations, and a *full* pass
walks every object of the oldest one with every thread stopped: the event
loop that sends the live samples too. A server freezes what exists once it
has started (the libraries, the lab, the app: :func:`gc.freeze` takes them out
of every pass), but a storm of joins (a lecture hall reconnecting after a
restart) makes tens of thousands of long-lived objects per second, the
sockets' own, and the passes that follow walked all of them: 100-190 ms
each, a sample held up as long (``benchmarks/bench_join_storm.py``, issue #26).

:class:`CollectorPolicy` freezes the survivors of every full pass as well, so
the next one walks only what came since (a quarter of what was there, by
CPython's own rule for when a full pass is due). What it freezes is never
collected while frozen: cycles of sockets that closed since stay in memory.
So when the lab is quiet (no run going) and enough has been frozen since
the last time, it thaws everything and collects it in one pass, at a moment
when a pause holds up no sample of a run.

Written by hand: no library tunes CPython's collector for a server's
lifecycle (the standard library gives the levers: :func:`gc.freeze`,
:func:`gc.unfreeze`, :data:`gc.callbacks`).
"""

from __future__ import annotations

import gc
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

__all__ = ["CollectorPolicy"]

log = logging.getLogger(__name__)


class CollectorPolicy:
    """Freeze what survives each full pass; thaw and collect it all when the lab is quiet.

    Parameters
    ----------
    quiet : callable
        Whether a long pause would hold up nothing that matters now (the lab:
        no run going on any of its rigs).
    check_every : float
        Seconds between looks at whether to thaw.
    thaw_growth : float
        Thaw once the frozen objects grew by this fraction of what was frozen
        after the last thaw (or at the server's start).
    """

    def __init__(
        self, quiet: Callable[[], bool], *, check_every: float = 60.0, thaw_growth: float = 0.5
    ) -> None:
        self._quiet = quiet
        self._check_every = check_every
        self._thaw_growth = thaw_growth
        self._baseline = gc.get_freeze_count()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.thaws = 0

    def start(self) -> None:
        """Freeze after every full pass from now on, and look for a quiet moment now and then."""
        gc.collect()
        gc.freeze()
        self._baseline = gc.get_freeze_count()
        gc.callbacks.append(self._after_pass)
        self._thread = threading.Thread(target=self._watch, name="collector", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop freezing and watching (what is frozen stays so)."""
        self._stop.set()
        if self._after_pass in gc.callbacks:
            gc.callbacks.remove(self._after_pass)
        if self._thread is not None:
            self._thread.join()

    def thaw_if_due(self) -> bool:
        """Thaw and collect everything if the lab is quiet and enough was frozen; whether it did."""
        grown = gc.get_freeze_count() - self._baseline
        if grown <= self._thaw_growth * self._baseline or not self._quiet():
            return False
        began = time.perf_counter()
        gc.unfreeze()
        found = gc.collect()
        gc.freeze()
        self._baseline = gc.get_freeze_count()
        self.thaws += 1
        log.info(
            "collector: %d unreachable objects collected in %.2f s, %d objects frozen",
            found,
            time.perf_counter() - began,
            self._baseline,
        )
        return True

    def _after_pass(self, phase: str, info: dict[str, Any]) -> None:
        # Called by the collector itself, before and after each pass; after a full one
        # its survivors are the server's long-lived objects (the sockets of a storm).
        if phase == "stop" and info["generation"] == 2:
            gc.freeze()

    def _watch(self) -> None:
        while not self._stop.wait(self._check_every):
            try:
                self.thaw_if_due()
            except Exception:  # a failed look must not end the next ones
                log.exception("collector: the quiet-time collection failed")
