"""The online MALSM and WLSM: the batch kernels one sample at a time.

Split from :mod:`thermolab.ident.online` (which holds the base class, the
estimate and :func:`~thermolab.ident.online.make_identifier`); the registry
names these classes, so nothing imports them directly.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from thermolab.errors import InvalidParameterError

from . import _validation as _v
from ._trust import with_warnings
from .models import NON_FINITE, NOT_EXCITED, ArxOrder
from .online import (
    _REASON_EXTRAS,
    Estimate,
    FloatArray,
    OnlineIdentifier,
    _fast_estimate,
    _first_order_estimate,
    _general_estimate,
    _model,
    _n_params,
    _with_trust,
)
from .recursive import check_recompute, check_wlsm_params, window_rows
from .registry import get_method
from .trajectory import Trajectory

__all__: list[str] = []


class _Recursive(OnlineIdentifier):
    """Shared machinery of MALSM and WLSM: the shifted record and the kernels' outputs.

    The per-sample path is kept short (a few microseconds): one compiled kernel
    call on preallocated arrays, which for first order also returns the new
    ``(status, a, b)``, and an :class:`Estimate` filled without ``__init__``.
    """

    def __init__(self, dt: float, params: dict[str, Any], order: ArxOrder, offset: str | float):
        super().__init__(dt, params)
        from . import _kernels, _kernels_first_order

        self._k = _kernels
        self._k1 = _kernels_first_order
        self._order = order
        self._offset = offset
        self._settings: dict[str, Any] = {}
        self._end_trajectory: Trajectory | None = None
        # offset="auto" online: "initial" until the input first changes (the only
        # handling a constant input identifies, and right for a record that starts
        # at rest or with a step at its first sample); then, if the input was on
        # before the change (a record settled under it, or moving), the constant
        # term is fitted and the record so far replayed. END decides over the
        # whole record as the batch function does.
        self._auto = self._keep_y = offset == _v.AUTO_OFFSET
        if self._auto:
            offset = "initial"
        self._initial = offset == "initial"
        self._constant = offset == "fit"
        self._first = order.is_first_order and not self._constant
        self._p = order.na + order.nb + int(self._constant)
        self._shift = offset if isinstance(offset, float) else 0.0
        self._y = np.empty(0)  # the raw output is not needed: the kernels read _ys
        self._ys = np.empty(self._u.size)
        self._W = np.empty((self._u.size, self._p), order="F")
        self._code = np.empty(self._u.size, dtype=np.int8)
        self._start = order.lag + 1

    def _growing(self) -> tuple[str, ...]:
        grown = ("_u", "_ys", "_W", "_code")
        return (*grown, "_y") if self._keep_y else grown

    def update(self, u: float, y: float) -> Estimate | None:
        uf, yf = self._checked_sample(u, y)
        k = self._n
        if k == self._u.size:
            self._grow()
        if self._keep_y:
            if k == 0:
                self._y = np.empty(self._u.size)
            self._y[k] = yf
            if self._auto and k and uf != self._u[k - 1]:
                self._auto = False  # decided once, at the first change
                if self._settled_under_input(k):
                    self._replay_with_constant(k)
        if k == 0 and self._initial:
            self._shift = yf
        self._u[k] = uf
        # y - 0.0 is y exactly, so this is the batch functions' shifted record bit for bit.
        self._ys[k] = yf - self._shift
        self._n = k + 1
        est = self._step(k)
        if est is not None:
            self._latest = est
        return est

    def _step(self, k: int) -> Estimate | None:
        # The one hook each recursive method (MALSM, WLSM) fills in: its kernel's update.
        raise NotImplementedError

    def _settled_under_input(self, k: int) -> bool:
        """Before the first input change at ``k``: input on and the output flat?

        A record that starts at ambient with the input switched on at its first
        sample rises at once (the paper's step and square wave); one settled
        under a nonzero input stays within its noise until the input changes,
        and its first output is not the ambient.
        """
        if self._u[0] == 0.0 or k < 3:
            return False
        from .operating_point import noise_level

        before = self._y[:k]
        scale = max(float(np.max(np.abs(before))), 1e-300)
        return float(np.ptp(before)) <= 3.0 * noise_level(before) + 1e-9 * scale

    def _replay_with_constant(self, k: int) -> None:
        """Switch to ``offset="fit"`` at sample ``k`` and replay samples ``0 .. k-1``."""
        try:
            fresh = type(self).from_settings(self.dt, {**self._settings, "offset": "fit"})
        except InvalidParameterError:
            return  # the window cannot hold a constant term: stay with "initial"
        assert isinstance(fresh, _Recursive)
        for i in range(k):
            fresh.update(float(self._u[i]), float(self._y[i]))
        params, settings, y = self.params, self._settings, self._y
        self.__dict__.update(fresh.__dict__)
        self.params, self._settings, self._y = params, settings, y
        self._offset = _v.AUTO_OFFSET
        self._auto, self._keep_y = False, True

    def _on_finish(self) -> Estimate | None:
        if self._latest is None:
            return None
        return _with_trust(self._latest, self.trajectory())

    def _from_status(self, k: int, status: int, a: float, b: float) -> Estimate | None:
        if status == 0:
            return _first_order_estimate(self.method, k, a, b, self.dt)
        if status == 1:
            return None
        return _fast_estimate(self.method, k, math.nan, math.nan, (), False, _REASON_EXTRAS[status])

    def _from_row(self, k: int) -> Estimate | None:
        status = int(self._code[k])
        if status == 0:
            return _general_estimate(self.method, k, self._W[k].copy(), self.dt, self._order)
        return self._from_status(k, status, math.nan, math.nan)

    def trajectory(self) -> Trajectory:
        if self._end_trajectory is not None:
            return self._end_trajectory
        n = self._n
        code = self._code[:n]
        live = Trajectory(
            method=self.method,
            dt=self.dt,
            W=self._W[:n].copy(order="F"),
            order=self._order,
            offset="fit" if self._constant else ("initial" if self._initial else self._offset),
            param_names=self._order.param_names(constant=self._constant),
            status=np.where((code == NOT_EXCITED) | (code == NON_FINITE), code, 0).astype(np.int8),
            params=dict(self.params),
        )
        if not self._finished:
            return live
        if self._offset == _v.AUTO_OFFSET and n > self._order.lag + 5:
            # END: the operating point decided over the whole record, exactly as
            # the batch function decides it (the same kernels give the same rows).
            batch = get_method(self.method).batch_function()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # kept in the trajectory's warnings
                tr: Trajectory = batch(self._u[:n], self._y[:n], self.dt, **self._settings)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                tr = with_warnings(live, None, None, self._settings.get("expected_sign"))
        self._end_trajectory = tr
        return tr


class _MovingWindow(_Recursive):
    method = "malsm"

    def __init__(
        self,
        dt: float,
        params: dict[str, Any],
        order: ArxOrder,
        offset: str | float,
        rows: int,
        every: int,
    ):
        super().__init__(dt, params, order, offset)
        self._buf, self._sums, self._shift_cols, self._ints = self._k.malsm_state(
            rows, every, self._p, self._first
        )

    @classmethod
    def from_settings(cls, dt: float, settings: dict[str, Any]) -> OnlineIdentifier:
        order, offset, common = _model(settings)
        window = settings["window"]
        rows = window_rows(order, window, _n_params(order, offset))
        every = check_recompute(settings["recompute_every"], rows)
        params = {"window": window, "recompute_every": every, **common}
        ident = cls(dt, params, order, offset, rows, every)
        ident._settings = dict(settings)
        return ident

    def _step(self, k: int) -> Estimate | None:
        if k < self._start:
            self._code[k] = 1
            self._W[k] = np.nan
            return None
        if self._first:
            status, a, b = self._k1.malsm2_chunk(
                self._u, self._ys, k, k + 1, self._buf, self._sums, self._ints, self._W, self._code
            )
            if status == 0:
                return _first_order_estimate("malsm", k, a, b, self.dt)
            return self._from_status(k, status, a, b)
        o = self._order
        self._k.malsm_chunk(
            self._u, self._ys, k, k + 1, o.na, o.nb, o.delay, self._constant,
            self._buf, self._sums, self._shift_cols, self._ints, self._W, self._code,
        )  # fmt: skip
        return self._from_row(k)


class _Weighted(_Recursive):
    method = "wlsm"

    def __init__(
        self,
        dt: float,
        params: dict[str, Any],
        order: ArxOrder,
        offset: str | float,
        gamma: float,
        W0: FloatArray,
        P0: FloatArray,
        paper: bool,
    ):
        super().__init__(dt, params, order, offset)
        self._gamma = gamma
        self._paper = paper
        self._W0 = W0
        self._Wk = W0.copy()
        self._Pk = P0.copy()

    @classmethod
    def from_settings(cls, dt: float, settings: dict[str, Any]) -> OnlineIdentifier:
        order, offset, common = _model(settings)
        form = settings["form"]
        gamma, W0, P0, paper = check_wlsm_params(
            settings["gamma"], settings["pmax"], settings["w0"], form, settings["p0"],
            _n_params(order, offset), order.na + order.nb,
        )  # fmt: skip
        params: dict[str, Any] = {
            "gamma": gamma,
            "pmax": settings["pmax"],
            "w0": W0.tolist(),
            "form": form,
            **common,
        }
        if settings["p0"] is not None:
            params["p0"] = P0.tolist()
        ident = cls(dt, params, order, offset, gamma, W0, P0, paper)
        ident._settings = dict(settings)
        return ident

    def _step(self, k: int) -> Estimate | None:
        if k < self._start:
            self._code[k] = 0
            self._W[k] = self._W0
            if self._first:
                return self._from_status(k, 0, float(self._W0[0]), float(self._W0[1]))
            return self._from_row(k)
        if self._first:
            status, a, b = self._k1.wlsm2_chunk(
                self._u, self._ys, k, k + 1, self._paper, self._gamma, self._Wk, self._Pk,
                self._W, self._code,
            )  # fmt: skip
            if status == 0:
                return _first_order_estimate("wlsm", k, a, b, self.dt)
            return self._from_status(k, status, a, b)
        o = self._order
        self._k.wlsm_chunk(
            self._u, self._ys, k, k + 1, o.na, o.nb, o.delay, self._constant, self._paper,
            self._gamma, self._Wk, self._Pk, self._W, self._code,
        )  # fmt: skip
        return self._from_row(k)
