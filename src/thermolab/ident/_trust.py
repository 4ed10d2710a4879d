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
from ._warning import IdentificationWarning
from .deadtime import DEFAULT_CRITERION, DelaySearch, default_max_delay, search_delay
from .models import ArxOrder
from .notes import FINAL, note
from .operating_point import OperatingPoint, decide_operating_point
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
    delay_search: DelaySearch | None


def check_record(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: object,
    order: object,
    offset: object,
    max_delay: object = None,
) -> CheckedRecord:
    """Check the record and ``dt``; resolve the order and dead time (:func:`resolve_model`)
    and ``offset`` (``"auto"``: from the data)."""
    u_arr, y_arr = _v.as_record(u, y)
    step = _v.check_dt(dt)
    ord_, off, op, search = resolve_model(u_arr, y_arr, step, order, offset, max_delay)
    return CheckedRecord(u_arr, y_arr, step, ord_, off, op, search)


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


def resolve_model(
    u: FloatArray,
    y: FloatArray,
    dt: float,
    order: object,
    offset: object,
    max_delay: object,
) -> tuple[ArxOrder, str | float, OperatingPoint | None, DelaySearch | None]:
    """The order, offset and, for an order not given, the dead time found in the record.

    ``order`` None is the dead-time handling ``"searched"``: first order with
    the delay of :func:`~thermolab.ident.deadtime.search_delay` (the least
    free-run simulation error, as LSM's default) over the whole record, before
    the block or recursive pass. A given order is used as it is.
    """
    if order is not None:
        given = _v.check_order(order)
        return given, *resolve_offset(u, y, dt, given, offset), None
    if max_delay is None:
        longest = default_max_delay(y.size)
    else:
        longest = _v.integer("max_delay", max_delay, 0, "0 turns the search off")
        if longest > 1000 or longest > y.size // 4:
            raise InvalidParameterError(
                f"max_delay must be at most 1000 and a quarter of the record "
                f"({y.size // 4} samples), got {longest}"
            )
    off_in = _v.check_offset_or_auto(offset)
    op: OperatingPoint | None = None
    if off_in == _v.AUTO_OFFSET:
        _v.check_min_samples(y.size, 5, "deciding the operating point")
        op = decide_operating_point(u, y, dt, max_delay=longest)
        off: str | float = op.handling
    else:
        off = off_in
    search = None
    if longest > 0:
        with np.errstate(all="ignore"):  # a record whose squares overflow: inf errors
            search = search_delay(u, y, off, longest, DEFAULT_CRITERION)
    return ArxOrder(1, 1, 0 if search is None else search.delay), off, op, search


def dead_time_params(search: DelaySearch | None, order: ArxOrder) -> dict[str, object]:
    """``{"dead_time": "searched" | "given", "delay": samples}`` for a trajectory's params."""
    return {"dead_time": "given" if search is None else "searched", "delay": order.delay}


def with_warnings(
    tr: Trajectory,
    op: OperatingPoint | None,
    t: npt.ArrayLike | None,
    expected_sign: int | None,
    *,
    window: int | None = None,
    search: DelaySearch | None = None,
    record: tuple[FloatArray, FloatArray] | None = None,
    memory: int | None = None,
) -> Trajectory:
    """Attach (and emit) the trajectory's warnings; returns the same trajectory.

    With the ``record`` and the ``memory`` of the final estimate (the samples
    it rests on: a window, a block, ``1/(1-gamma)`` for forgetting), a final
    estimate whose samples hold no excitation is flagged (:func:`_unexcited`).
    """
    notes = list(op.warnings) if op is not None else []
    if search is not None and search.warning:
        notes.append(search.warning)
    if record is not None and memory is not None and tr.final.valid:
        with np.errstate(all="ignore"):
            unexcited = _unexcited(tr, *record, memory)
        if unexcited:
            notes.append(unexcited)
    final = tr.final
    duration = tr.n_samples * tr.dt
    if final.valid:
        notes += [
            f"{FINAL}{w}"
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
                last = min(first + window - 2, tr.n_samples - 1)
                at = float(t_arr[first - 1])
                notes.append(
                    note("windows_across_gap", window=window, first=first, last=last, at=at)
                )
    if not notes:
        return tr
    for said in notes:
        warnings.warn(said, IdentificationWarning, stacklevel=3)
    # The trajectory is frozen and its K/tau are derived at construction; the
    # warnings need them, so they are set afterwards rather than rebuilding it.
    object.__setattr__(tr, "warnings", tuple(notes))
    return tr


def _unexcited(tr: Trajectory, u: FloatArray, y: FloatArray, memory: int) -> str | None:
    """Why the final estimate rests on samples without excitation, or None.

    The last ``memory`` samples excite the model when the input changes in
    them or the output still moves by more than ten times its noise (from the
    third differences, at least half the readings' quantum): a settled step's
    tail only fits the noise (τ ≈ half a sample on the kit twin). The warning says where the last
    excited samples end and what to do instead.
    """
    n = y.size
    span = max(1, min(memory, n))
    # The noise from third differences (white noise of sd s gives a median
    # |Δ³y| of about 3 s; a smooth response almost none), and at least half
    # the readings' quantum (the smallest change seen), which a quantised
    # sensor toggles by when settled.
    tail = y[-min(n, 100_000) :]
    jerk = np.abs(np.diff(tail, 3))
    moves = np.abs(np.diff(tail))
    moves = moves[moves > 0.0]
    scale = max(float(np.max(np.abs(y))), 1e-300)
    noise = max(
        float(np.median(jerk)) / 3.0 if jerk.size else 0.0,
        float(moves.min()) / 2.0 if moves.size else 0.0,
        1e-9 * scale,
    )

    def excited(end: int) -> bool:
        lo = max(0, end - span + 1)
        seg_u, seg_y = u[lo : end + 1], y[lo : end + 1]
        return bool(np.ptp(seg_u) > 0.0 or np.ptp(seg_y) > 10.0 * noise)

    if excited(n - 1):
        return None
    # The last sample whose trailing memory still saw the input change or the output move.
    changes = np.flatnonzero(np.diff(u) != 0.0)
    last_change = int(changes[-1]) + 1 if changes.size else 0
    stride = max(1, span // 4)
    k_ok = next((k for k in range(n - 1, last_change - 1, -stride) if excited(k)), None)
    if k_ok is None:
        return note("final_not_excited", span=span)
    return note("final_not_excited_since", span=span, excited=k_ok)
