"""Excitation signals and their text syntax.

Five generators drive the rig's input: a constant, a step, a square wave (the
paper's *Automatic* option), a sine and a pseudo-random binary sequence. Each
is an immutable :class:`Signal` with ``value(t)`` (one time),
``sample(t_array)`` (many) and ``spec``, its canonical text in the one syntax
shared by the command line and the server::

    const:U                           constant U volts
    step:U0:U1@T                      U0 before T seconds, U1 from T on
    square:LOW:HIGH:FREQ_HZ           square wave, HIGH for the first half period
    sine:OFFSET:AMPLITUDE:FREQ_HZ     OFFSET + AMPLITUDE sin(2 pi FREQ_HZ t)
    prbs:LOW:HIGH:BIT_SECONDS[:SEED]  maximum-length PRBS, one bit per BIT_SECONDS

:func:`parse_signal` reads that syntax; ``parse_signal(s.spec, s.limits) == s``
for every signal ``s``.

Time ``t`` is in seconds from the start of the run. Values are volts and never
leave the input range ``limits`` (±10 V, the paper's rig, by default): the
levels a signal is built from must lie inside it (an out-of-range level is an
error, not silently changed), and the excursions of a sine beyond it are
clipped.

Edges. Steps, square-wave edges and PRBS bit boundaries are half-open: the
new level holds *at* the edge time. Times are computed in floating point
(``k * dt``), so a time within about 1e-9 of an edge (relative to the edge
spacing) counts as at the edge; sampled at ``t = k dt`` every edge lands on the
sample it is meant for.

The package's modules: :mod:`~thermolab.signals._base` (:class:`Signal`, the
input range and the edge rule), :mod:`~thermolab.signals._waves` (constant, step,
square, sine), :mod:`~thermolab.signals._prbs` (the PRBS) and
:mod:`~thermolab.signals._syntax` (:func:`parse_signal`). Import from
:mod:`thermolab.signals`.
"""

from __future__ import annotations

from ._base import DEFAULT_LIMITS, Signal
from ._prbs import PRBS
from ._syntax import SIGNAL_SYNTAX, parse_signal
from ._waves import Constant, Sine, Square, Step, automatic_square

__all__ = [
    "DEFAULT_LIMITS",
    "PRBS",
    "SIGNAL_SYNTAX",
    "Constant",
    "Signal",
    "Sine",
    "Square",
    "Step",
    "automatic_square",
    "parse_signal",
]
