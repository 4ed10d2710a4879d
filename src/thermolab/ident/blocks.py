"""Least squares over consecutive blocks: the paper's LSM(2) and LSM(3)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from . import _regression as _reg
from . import _validation as _v
from ._trust import check_record, dead_time_params, rows_inside, with_warnings
from .models import NOT_EXCITED, ArxOrder
from .registry import SETTINGS
from .trajectory import Trajectory

__all__ = ["block_least_squares", "block_rows"]

#: Samples solved in one batched call (a group of whole blocks).
_GROUP_ROWS = 1 << 16


def block_rows(order: ArxOrder, block: int, n_params: int, n_samples: int) -> tuple[int, int]:
    """``(rows per block, number of full blocks)``, checking the block is big enough."""
    rows = rows_inside("block", order, block, n_params)
    _v.check_min_samples(n_samples, block, f"one block of {block} samples")
    return rows, n_samples // block


def block_least_squares(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    block: int = SETTINGS["block"].default,
    *,
    order: ArxOrder | None = None,
    offset: str | float = SETTINGS["offset"].default,
    t: npt.ArrayLike | None = None,
    expected_sign: int | None = SETTINGS["expected_sign"].default,
    max_delay: int | None = SETTINGS["max_delay"].default,
) -> Trajectory:
    """Least squares over consecutive non-overlapping blocks: the paper's LSM(2) and LSM(3).

    Block ``j`` is the samples ``j*block .. (j+1)*block - 1``; its estimate uses
    the regression rows whose samples all lie inside the block
    (``block - 1 - order.lag`` rows) and is placed at the block's last sample.
    A trailing partial block gives no estimate. Each block is solved like
    :func:`least_squares` (SVD, no inverse), all blocks in one batched call.

    Parameters
    ----------
    u, y : array_like
        Input and output samples in absolute volts, same length.
    dt : float
        Sample period in seconds, > 0.
    block : int, optional
        Samples per block, default 100; at least ``order.lag + 1 + n_params``.
    order : ArxOrder, optional
        Model structure. Default: first order with the dead time searched in
        the whole record as :func:`~thermolab.ident.least_squares` does
        (``params["dead_time"]`` says ``"searched"`` or ``"given"``,
        ``params["delay"]`` the delay used).
    offset : {"auto", "initial", "fit", "none"} or float, optional
        As in :func:`least_squares`; ``"initial"`` takes the ambient from the
        record's first sample, for every block. Default ``"auto"``, decided from
        the whole record (until this release ``"initial"``).
    t : array_like, optional
        Sample times: blocks that span a gap in time, and jitter, are flagged.
    expected_sign : {1, -1}, optional
        The sign the gain must have; a final gain of the other sign is flagged.
    max_delay : int, optional
        Longest dead time searched when ``order`` is None (as in ``least_squares``).

    Returns
    -------
    Trajectory
        Estimates at samples ``block-1, 2*block-1, ...`` and NaN between them
        (``reason_code`` 1); a block whose regression is singular (not excited)
        has reason code 2.

    Raises
    ------
    InvalidDataError
        If the data are not finite, differ in length, or hold less than one block.
    InvalidParameterError
        If ``block``, ``dt``, ``order`` or ``offset`` is not allowed.

    Examples
    --------
    The paper's LSM(3): a 4↔6 V square wave at 0.1 Hz, an estimate every 100 samples.

    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL
    >>> u = np.where((np.arange(2000) // 5) % 2 == 0, 6.0, 4.0)
    >>> tr = block_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, block=100)
    >>> np.flatnonzero(tr.valid)[:3], round(tr.stats()["tau"]["min"], 6)
    (array([ 99, 199, 299]), 250.126233)
    """
    u_arr, y_arr, step, ord_, off, op, search = check_record(u, y, dt, order, offset, max_delay)
    size = _v.integer("block", block, 1, "samples per block")
    p = ord_.na + ord_.nb + int(off == "fit")
    rows, n_blocks = block_rows(ord_, size, p, y_arr.size)
    # Every block in the frame of the whole record: "initial" subtracts the
    # record's y[0] from each block, which a group's own first sample is not.
    y_shift, constant = _reg.offset_shift(off, float(y_arr[0]))
    frame: str | float = "fit" if constant else y_shift
    W = np.full((y_arr.size, p), np.nan)
    at = np.arange(1, n_blocks + 1) * size - 1
    status = np.zeros(y_arr.size, dtype=np.int8)
    idx = np.arange(n_blocks)[:, None] * size + np.arange(rows)[None, :]
    # A group of blocks at a time: the batched SVD's work arrays (several copies
    # of D) stay small on a 10⁷-sample record; each block's solve is the same.
    group = max(1, _GROUP_ROWS // size)
    for first in range(0, n_blocks, group):
        last = min(first + group, n_blocks)
        lo, hi = first * size, last * size
        reg = _reg.build(u_arr[lo:hi], y_arr[lo:hi], ord_, frame)
        sol = _reg.solve(reg.D[idx[: last - first]], reg.Y[idx[: last - first]])
        W[at[first:last]] = sol.W
        status[at[first:last][~sol.ok]] = NOT_EXCITED
    tr = Trajectory(
        method="blockls",
        dt=step,
        W=W,
        order=ord_,
        offset=off,
        param_names=ord_.param_names(constant=constant),
        status=status,
        params={"block": size, **dead_time_params(search, ord_)},
        operating_point=op,
    )
    return with_warnings(
        tr, op, t, expected_sign, window=size, search=search, record=(u_arr, y_arr), memory=size
    )
