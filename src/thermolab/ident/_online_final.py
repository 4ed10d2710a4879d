"""The online SRM, LSM, block LS and OE: methods that answer at END or at a block's end.

Split from :mod:`thermolab.ident.online` (the base class, the estimate and
:func:`~thermolab.ident.online.make_identifier`); the registry names these
classes, so nothing imports them directly.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from thermolab.errors import InsufficientExcitationError, InvalidDataError

from . import _regression as _reg
from . import _validation as _v
from .batch import least_squares
from .blocks import block_least_squares, block_rows
from .models import NOT_EXCITED, ArxOrder
from .online import (
    _REASON_EXTRAS,
    Estimate,
    OnlineIdentifier,
    _fast_estimate,
    _first_order_estimate,
    _general_estimate,
    _invalid,
    _model,
    _n_params,
    _with_trust,
)
from .trajectory import Trajectory

__all__: list[str] = []


class _StepResponse(OnlineIdentifier):
    method = "srm"

    def _on_finish(self) -> Estimate | None:
        if self._n == 0:
            return None
        from .step import step_response

        u, y = self._record()
        t = np.arange(self._n) * self.dt
        try:
            with warnings.catch_warnings():
                # The warnings are also in the result; do not repeat them at END.
                warnings.simplefilter("ignore")
                res = step_response(t, u, y, **self.params)
        except InvalidDataError as exc:
            return _invalid(self.method, self._n - 1, str(exc))
        extras = res.to_dict()
        extras.pop("method", None)
        valid = math.isfinite(res.K) and math.isfinite(res.tau) and res.tau > 0.0
        return Estimate(self.method, self._n - 1, res.K, res.tau, (), valid, True, extras)


class _LeastSquares(OnlineIdentifier):
    method = "lsm"

    def __init__(
        self, dt: float, params: dict[str, Any], order: ArxOrder | None, offset: str | float
    ):
        super().__init__(dt, params)
        self._order = order
        self._offset = offset
        self._result: Any = None

    @classmethod
    def from_settings(cls, dt: float, settings: dict[str, Any]) -> OnlineIdentifier:
        order, offset, common = _model(settings, search=True)
        trust = {k: settings[k] for k in ("max_delay", "holdout", "expected_sign")}
        return cls(dt, {**common, **trust}, order, offset)

    def _on_finish(self) -> Estimate | None:
        if self._n == 0:
            return None
        u, y = self._record()
        p = self.params
        try:
            with warnings.catch_warnings():
                # The warnings are kept in extras["warnings"]; do not repeat them at END.
                warnings.simplefilter("ignore")
                res = least_squares(
                    u, y, self.dt, order=self._order, offset=self._offset,
                    max_delay=p["max_delay"], holdout=p["holdout"],
                    expected_sign=p["expected_sign"],
                )  # fmt: skip
        except InvalidDataError as exc:
            return _invalid(self.method, self._n - 1, str(exc))
        self._result = res
        summary = res.to_dict()
        extras: dict[str, Any] = {
            "stderr": res.stderr.tolist(),
            "param_names": list(res.param_names),
            **{k: summary[k] for k in _LSM_EXTRAS},
        }
        if res.model.reason is not None:
            extras["reason"] = res.model.reason
        return Estimate(
            self.method, self._n - 1, res.K, res.tau, tuple(res.W.tolist()), res.model.valid,
            True, extras,
        )  # fmt: skip

    def trajectory(self) -> Trajectory:
        res = self._result
        order = res.order if res is not None else (self._order or ArxOrder())
        offset = res.offset if res is not None else self._offset
        constant = offset == "fit"
        W = np.full((self._n, order.na + order.nb + int(constant)), np.nan)
        if res is not None:
            W[-1] = res.W
        return Trajectory(
            "lsm", self.dt, W, order, "initial" if offset == "auto" else offset,
            order.param_names(constant=constant), params=dict(self.params),
        )  # fmt: skip


#: What the online LSM's final estimate carries from the batch result.
_LSM_EXTRAS = (
    "K_stderr", "tau_stderr", "cond", "cond_scaled", "fit_one_step", "fit_simulation",
    "fit_holdout", "ambient", "theta", "order", "offset", "operating_point", "delay_search",
    "residual_test", "warnings", "trusted",
)  # fmt: skip


class _OutputError(OnlineIdentifier):
    """The output-error fit at END (it needs the whole record, like LSM)."""

    method = "oe"

    def _on_finish(self) -> Estimate | None:
        if self._n == 0:
            return None
        from .oe import output_error

        u, y = self._record()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # kept in extras["warnings"]
                res = output_error(u, y, self.dt, **self.params)
        except (InvalidDataError, InsufficientExcitationError) as exc:
            return _invalid(self.method, self._n - 1, str(exc))
        extras = res.to_dict()
        extras.pop("method", None)
        return Estimate(self.method, self._n - 1, res.K, res.tau, (), res.model.valid, True, extras)


class _BlockLeastSquares(OnlineIdentifier):
    method = "blockls"

    def __init__(
        self, dt: float, params: dict[str, Any], order: ArxOrder, offset: str | float, block: int
    ):
        super().__init__(dt, params)
        self._order = order
        self._offset = offset
        self._block = block
        self._block_offset: str | float = offset
        # offset="auto": decided from the record so far at a block's end, again
        # each time the record has doubled (so the decisions cost O(n) in all).
        self._decided_at = 0
        self._expected_sign = params.get("expected_sign")

    @classmethod
    def from_settings(cls, dt: float, settings: dict[str, Any]) -> OnlineIdentifier:
        order, offset, common = _model(settings)
        block = settings["block"]
        block_rows(order, block, _n_params(order, offset), block)
        params = {"block": block, **common, "expected_sign": settings["expected_sign"]}
        return cls(dt, params, order, offset, block)

    def _on_sample(self, k: int, u: float, y: float) -> Estimate | None:
        if k == 0 and self._offset == "initial":
            self._block_offset = y  # every block is taken from the record's first sample
        if (k + 1) % self._block:
            return None
        if self._offset == _v.AUTO_OFFSET and k + 1 >= 2 * self._decided_at:
            self._decide(k + 1)
        lo = k + 1 - self._block
        reg = _reg.build(self._u[lo : k + 1], self._y[lo : k + 1], self._order, self._block_offset)
        sol = _reg.solve(reg.D[None], reg.Y[None])
        if not sol.ok[0]:
            return _fast_estimate(
                self.method, k, math.nan, math.nan, (), False, _REASON_EXTRAS[NOT_EXCITED]
            )
        W = sol.W[0]
        if self._order.is_first_order and W.size == 2:
            return _first_order_estimate(self.method, k, float(W[0]), float(W[1]), self.dt)
        return _general_estimate(self.method, k, W, self.dt, self._order)

    def _decide(self, n: int) -> None:
        from .operating_point import decide_operating_point

        u, y = self._u[:n], self._y[:n]
        try:
            handling = decide_operating_point(u, y, self.dt, order=self._order).handling
        except InvalidDataError:
            handling = "initial"
        self._block_offset = float(y[0]) if handling == "initial" else "fit"
        self._decided_at = n

    def _on_finish(self) -> Estimate | None:
        if self._latest is None:
            return None
        # The batch trajectory decides the operating point over the whole record
        # and carries the warnings.
        return _with_trust(self._latest, self.trajectory())

    def trajectory(self) -> Trajectory:
        u, y = self._record()
        if self._n < self._block:
            p = self._order.na + self._order.nb + int(self._offset == "fit")
            return Trajectory(
                "blockls", self.dt, np.full((self._n, p), np.nan), self._order, self._offset,
                self._order.param_names(constant=self._offset == "fit"), params=dict(self.params),
            )  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # kept in the trajectory's warnings
            return block_least_squares(
                u, y, self.dt, self._block, order=self._order, offset=self._offset,
                expected_sign=self._expected_sign,
            )  # fmt: skip
