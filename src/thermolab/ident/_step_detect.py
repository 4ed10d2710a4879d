"""Step response method, reading the record: the step, the noise, the drift, the first response.

The helpers of :func:`thermolab.ident.step.step_response` that look at the
record before anything is fitted (:mod:`thermolab.ident._step_fit` fits).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from thermolab.errors import InsufficientExcitationError, InvalidDataError

from .notes import note

__all__ = ["find_step", "first_response", "median_dt", "noise_level", "pre_step_drift"]

FloatArray = npt.NDArray[np.float64]

_OTHER_STEP_FRACTION = 0.1
# Samples the tail fit needs at least (three parameters and something to spare).


def find_step(u: FloatArray, u_initial: float | None) -> tuple[int, float, float]:
    """Index of the first sample with the new input, and the levels either side."""
    ext = u if u_initial is None else np.concatenate([[u_initial], u])
    jumps = np.abs(np.diff(ext))
    scale = max(1.0, float(np.max(np.abs(ext))))
    if jumps.size == 0 or float(jumps.max()) <= 1e-12 * scale:
        code = "no_step" if u_initial is not None else "no_step_first_sample"
        raise InsufficientExcitationError(note(code, u=float(ext[0])))
    j = int(np.argmax(jumps))
    others = np.flatnonzero(jumps > _OTHER_STEP_FRACTION * jumps[j])
    others = others[others != j]
    if others.size:
        offset = 0 if u_initial is None else 1
        where = ", ".join(str(int(i) + 1 - offset) for i in others[:5])
        raise InvalidDataError(
            f"the input changes more than once (also at sample {where}"
            f"{', ...' if others.size > 5 else ''}; the main step is at sample "
            f"{j + 1 - offset}): the step method needs a single step; cut the record to one "
            "step or use a least-squares method"
        )
    ks = j + 1 - (0 if u_initial is None else 1)
    return ks, float(np.mean(ext[: j + 1])), float(np.mean(ext[j + 1 :]))


def noise_level(x: FloatArray) -> float:
    """Robust noise standard deviation from the sample-to-sample differences."""
    if x.size < 3:
        return 0.0
    d = np.diff(x)
    # MAD of the differences of the differences ignores a smooth trend; the
    # second difference of white noise has variance 6 sigma^2.
    dd = np.diff(d)
    return float(np.median(np.abs(dd - np.median(dd))) / 0.6745 / math.sqrt(6.0))


def pre_step_drift(y_pre: FloatArray, noise: float) -> float:
    """Change of the output across the samples before the step (0 when too few)."""
    if y_pre.size < 10:
        return 0.0
    m = max(1, y_pre.size // 5)
    drift = float(np.mean(y_pre[-m:]) - np.mean(y_pre[:m]))
    return drift if abs(drift) > 3.0 * noise / math.sqrt(m) else 0.0


def median_dt(t: FloatArray) -> float:
    """Median sample period (NaN for a single sample)."""
    return float(np.median(np.diff(t))) if t.size > 1 else math.nan


def first_response(tr: FloatArray, yr: FloatArray, noise: float) -> float:
    """Time of the last sample before ``yr`` (rising) leaves the noise band for good."""
    band = max(4.0 * noise, 1e-12 * max(1.0, float(np.max(np.abs(yr)))))
    outside = yr > band
    inside = np.flatnonzero(~outside)
    if outside.all():
        return 0.0
    if inside.size == 0 or inside[-1] == yr.size - 1:
        return math.nan
    return float(tr[int(inside[-1])])
