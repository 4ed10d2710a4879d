"""What the block and recursive methods share to make their trajectories trustworthy.

``offset="auto"`` resolved once for the whole record, and the warnings a
trajectory carries: an undetermined operating point, implausible final
estimates, windows or blocks that span a gap in time, timing jitter.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError

from . import _validation as _v
from . import diagnostics as _diag
from .models import ArxOrder
from .operating_point import OperatingPoint, decide_operating_point
from .step import IdentificationWarning
from .trajectory import Trajectory

FloatArray = npt.NDArray[np.float64]


class CheckedRecord(NamedTuple):
    """A block or recursive method's record and common arguments, checked once."""

    u: FloatArray
    y: FloatArray
    dt: float
    order: ArxOrder
    offset: str | float
    operating_point: OperatingPoint | None


def check_record(
    u: npt.ArrayLike, y: npt.ArrayLike, dt: object, order: object, offset: object
) -> CheckedRecord:
    """Check the record, ``dt`` and ``order``; resolve ``offset`` (``"auto"``: from the data)."""
    u_arr, y_arr = _v.as_record(u, y)
    step = _v.check_dt(dt)
    ord_ = _v.check_order(order)
    off, op = resolve_offset(u_arr, y_arr, step, ord_, offset)
    return CheckedRecord(u_arr, y_arr, step, ord_, off, op)


def rows_inside(name: str, order: ArxOrder, size: int, n_params: int) -> int:
    """Regression rows inside ``size`` consecutive samples (a window, a block), checking enough."""
    rows = size - 1 - order.lag
    if rows < n_params:
        raise InvalidParameterError(
            f"{name} must be >= {order.lag + 1 + n_params} samples to give {n_params} regression "
            f"rows for {n_params} parameters with order {order}, got {size}"
        )
    return rows


def resolve_offset(
    u: FloatArray, y: FloatArray, dt: float, order: ArxOrder, offset: object
) -> tuple[str | float, OperatingPoint | None]:
    """The offset mode to use and, for ``"auto"``, the decision behind it."""
    off = _v.check_offset_or_auto(offset)
    if off != _v.AUTO_OFFSET:
        return off, None
    _v.check_min_samples(y.size, order.lag + 5, f"deciding the operating point for {order}")
    op = decide_operating_point(u, y, dt, order=order)
    return op.handling, op


def with_warnings(
    tr: Trajectory,
    op: OperatingPoint | None,
    t: npt.ArrayLike | None,
    expected_sign: int | None,
    *,
    window: int | None = None,
) -> Trajectory:
    """Attach (and emit) the trajectory's warnings; returns the same trajectory."""
    notes = list(op.warnings) if op is not None else []
    final = tr.final
    duration = tr.n_samples * tr.dt
    if final.valid:
        notes += [
            f"final estimate: {w}"
            for w in _diag.plausibility_warnings(
                final.K, final.tau, tr.dt, duration, expected_sign=expected_sign
            )
        ]
    if t is not None:
        t_arr, steps = _v.check_time_steps(t, tr.n_samples)
        notes += _diag.timing_warnings_from_steps(t_arr, steps)
        if window is not None and t_arr.size > 2:
            gaps = np.flatnonzero(steps > 1.5 * float(np.median(steps)))
            if gaps.size:
                first = int(gaps[0]) + 1
                notes.append(
                    f"estimates across a gap: the {window}-sample windows ending at samples "
                    f"{first} to {min(first + window - 2, tr.n_samples - 1)} hold samples on both "
                    f"sides of the gap after t = {float(t_arr[first - 1]):.6g} s, so they regress "
                    "samples that are not one period apart; do not trust them"
                )
    if not notes:
        return tr
    for note in notes:
        warnings.warn(note, IdentificationWarning, stacklevel=3)
    # The trajectory is frozen and its K/tau are derived at construction; the
    # warnings need them, so they are set afterwards rather than rebuilding it.
    object.__setattr__(tr, "warnings", tuple(notes))
    return tr
