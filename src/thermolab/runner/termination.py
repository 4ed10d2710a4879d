"""Turn SIGTERM (and SIGINT) into an exception, so that a run ends through its safe state.

Python turns SIGINT into :class:`KeyboardInterrupt` by itself; SIGTERM, by
default, kills the process at once and leaves a heater as it was. Inside
:func:`termination_signals` both raise in the main thread (SIGTERM as
:class:`Terminated`), wherever the sampling loop is (also in the middle of a
sleep), so the run's cleanup puts the actuator at its safe value and closes
the record before the process exits.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["Terminated", "interrupt_signal", "termination_signals"]


class Terminated(BaseException):
    """The process received SIGTERM (a :class:`BaseException`, like KeyboardInterrupt).

    Parameters
    ----------
    signum : int
        The signal number received.
    """

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__(f"terminated by {signal.Signals(signum).name}")
        self.signum = int(signum)


def interrupt_signal(exc: BaseException) -> int | None:
    """Return the signal number an interruption stands for, or ``None``.

    Parameters
    ----------
    exc : BaseException
        An exception caught while running.

    Returns
    -------
    int or None
        ``SIGINT`` for :class:`KeyboardInterrupt`, the signal of a
        :class:`Terminated`, ``N`` for ``SystemExit(128 + N)``, otherwise ``None``.

    Examples
    --------
    >>> interrupt_signal(KeyboardInterrupt()) == signal.SIGINT
    True
    >>> interrupt_signal(Terminated()) == signal.SIGTERM
    True
    >>> interrupt_signal(SystemExit(143)) == signal.SIGTERM
    True
    >>> interrupt_signal(ValueError()) is None
    True
    """
    if isinstance(exc, KeyboardInterrupt):
        return int(signal.SIGINT)
    if isinstance(exc, Terminated):
        return exc.signum
    # A handler that exits the conventional way (the TCLab driver's, say) raises
    # SystemExit(128 + signum).
    if isinstance(exc, SystemExit) and isinstance(exc.code, int) and 128 < exc.code < 128 + 65:
        return exc.code - 128
    return None


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signum)


@contextmanager
def termination_signals() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` in the main thread.

    SIGINT keeps raising :class:`KeyboardInterrupt` (its handler is restored
    to Python's default if something had replaced it). The previous handlers
    come back on exit. Outside the main thread (where Python does not allow
    signal handlers) the block does nothing: whoever owns the main thread
    must stop the run, with :meth:`~thermolab.runner.Experiment.abort`.

    Yields
    ------
    None

    Examples
    --------
    >>> with termination_signals():
    ...     signal.getsignal(signal.SIGTERM) is _raise_terminated
    True
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous_term = signal.signal(signal.SIGTERM, _raise_terminated)
    previous_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous_term)
        signal.signal(signal.SIGINT, previous_int)
