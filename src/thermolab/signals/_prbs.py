"""The pseudo-random binary sequence (PRBS) signal, from a seeded maximum-length sequence.

Re-exported by :mod:`thermolab.signals`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.
from thermolab.errors import InvalidParameterError

from ._base import FloatArray, Signal, check_level, check_number, edge_index, fmt

__all__ = ["PRBS"]

# Register length of the PRBS: a period of 32767 bits (the ITU PRBS15 length), far
# longer than any run, yet small enough to tabulate once per seed.
_PRBS_BITS = 15


@dataclass(frozen=True)
class PRBS(Signal):
    """A maximum-length pseudo-random binary sequence between ``low`` and ``high``.

    Parameters
    ----------
    low, high : float
        The two levels in volts, ``low <= high``, inside ``limits``.
    bit_seconds : float
        Duration of one bit in seconds, > 0.
    seed : int, optional
        Non-negative integer choosing the sequence's starting state (default 0).
        The same seed always gives the same signal, on every machine.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If a level is outside ``limits``, ``low > high``, ``bit_seconds <= 0`` or
        ``seed`` is not a non-negative integer.

    Notes
    -----
    The bits are a 15-bit maximum-length sequence (period 32767 bits, from
    :func:`scipy.signal.max_len_seq`): its autocorrelation is flat, which is what
    makes a PRBS a good identification input. The seed is hashed (SplitMix64)
    into the register's non-zero starting state. Bit ``i`` covers
    ``[i bit_seconds, (i+1) bit_seconds)``; a 1 bit is ``high``.

    Examples
    --------
    >>> s = PRBS(0.0, 4.0, bit_seconds=5.0, seed=3)
    >>> s.spec
    'prbs:0:4:5:3'
    >>> bool(np.all(s.sample([0.0, 1.0, 4.9]) == s.value(0.0)))
    True
    """

    low: float
    high: float
    bit_seconds: float
    seed: int = 0
    _bits: npt.NDArray[np.bool_] = field(init=False, repr=False, compare=False)

    def _validate(self) -> None:
        check_level(self, "low", self.low)
        check_level(self, "high", self.high)
        if self.low > self.high:
            raise InvalidParameterError(
                f"PRBS: LOW ({fmt(self.low)}) must not exceed HIGH ({fmt(self.high)})"
            )
        check_number(self, "bit_seconds", self.bit_seconds, minimum=0.0, inclusive=False, unit="s")
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int | np.integer)
            or self.seed < 0
        ):
            raise InvalidParameterError(
                f"PRBS: SEED must be a non-negative integer, got {self.seed!r}"
            )
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "_bits", _mls_bits(self.seed))

    @property
    def spec(self) -> str:
        """Canonical text ``prbs:LOW:HIGH:BIT_SECONDS:SEED`` (the seed always shown)."""
        return f"prbs:{fmt(self.low)}:{fmt(self.high)}:{fmt(self.bit_seconds)}:{self.seed}"

    def _raw(self, t: FloatArray) -> FloatArray:
        index = edge_index(t / self.bit_seconds) % self._bits.size
        return np.where(self._bits[index], self.high, self.low)


@functools.lru_cache(maxsize=64)
def _mls_bits(seed: int) -> npt.NDArray[np.bool_]:
    state = _splitmix64(seed) & ((1 << _PRBS_BITS) - 1) or 1
    register = np.array([(state >> i) & 1 for i in range(_PRBS_BITS)], dtype=np.int8)
    from scipy.signal import max_len_seq

    seq, _ = max_len_seq(_PRBS_BITS, state=register)
    bits = np.asarray(seq, dtype=bool)
    bits.setflags(write=False)
    return bits


def _splitmix64(seed: int) -> int:
    mask = (1 << 64) - 1
    z = (seed + 0x9E3779B97F4A7C15) & mask
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return z ^ (z >> 31)
