"""Sample-by-sample identifiers for a running experiment (the runner and the lab server).

:func:`make_identifier` returns an :class:`OnlineIdentifier` for one of the
paper's methods. Feed it every sample in order with :meth:`~OnlineIdentifier.update`
and close the test with :meth:`~OnlineIdentifier.finish` (the paper's END
button); each returns an :class:`Estimate` when the method has one:

========== ==================================================================
``srm``    at ``finish()`` (the step response needs the whole record)
``lsm``    at ``finish()`` (least squares over the whole record)
``blockls`` at the last sample of every full block
``malsm``  at every sample once the first window is full
``wlsm``   at every sample (``W0`` itself at the first one)
========== ==================================================================

Fed the same samples, an online identifier gives the estimates of the batch
function — the recursive methods run the very same compiled kernels one
sample at a time, so ``W`` is identical bit for bit and ``K``/``tau`` agree to
the last digit or two (a scalar ``log`` against NumPy's vectorised one).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Literal, overload

import numpy as np
import numpy.typing as npt

from thermolab.errors import (
    IdentifierStateError,
    InsufficientExcitationError,
    InvalidDataError,
    InvalidParameterError,
)
from thermolab.jsonsafe import json_safe

from . import _regression as _reg
from . import _validation as _v
from ._trust import with_warnings
from .batch import least_squares
from .blocks import block_least_squares, block_rows
from .models import (
    INVALID_REASONS,
    NON_FINITE,
    NON_POSITIVE_POLE,
    NOT_EXCITED,
    UNSTABLE,
    ArxOrder,
    discrete_to_first_order,
)
from .recursive import check_recompute, check_wlsm_params, window_rows
from .registry import check_settings, get_method
from .trajectory import Trajectory

__all__ = ["Estimate", "OnlineIdentifier", "make_identifier"]

FloatArray = npt.NDArray[np.float64]

_NO_EXTRAS: Mapping[str, Any] = MappingProxyType({})
_REASON_EXTRAS = tuple(
    MappingProxyType({"reason": r}) if r is not None else _NO_EXTRAS for r in INVALID_REASONS
)


@dataclass(frozen=True)
class Estimate:
    """One estimate from an online identifier.

    Parameters
    ----------
    method : str
        ``"srm"``, ``"lsm"``, ``"blockls"``, ``"malsm"`` or ``"wlsm"``.
    k : int
        Index of the sample whose arrival made the estimate available.
    K, tau : float
        Gain and time constant (seconds); NaN when not ``valid``.
    W : tuple of float
        Discrete parameters (empty for ``srm``).
    valid : bool
        True when ``K`` and ``tau`` are meaningful.
    final : bool, optional
        True for the estimate returned by ``finish()``.
    extras : mapping, optional
        Method-specific details: ``reason`` when not valid; standard errors and
        fits for ``lsm``; the step found and the warnings for ``srm``.

    Examples
    --------
    >>> e = Estimate("malsm", 99, 0.14009, 250.126233, (0.99601, 0.000558959), True)
    >>> e.to_dict()["tau"]
    250.126233
    """

    method: str
    k: int
    K: float
    tau: float
    W: tuple[float, ...]
    valid: bool
    final: bool = False
    extras: Mapping[str, Any] = field(default_factory=lambda: _NO_EXTRAS)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the fields (NaN and inf become ``None``)."""
        return {
            "method": self.method,
            "k": self.k,
            "K": json_safe(self.K),
            "tau": json_safe(self.tau),
            "W": json_safe(self.W),
            "valid": self.valid,
            "final": self.final,
            "extras": json_safe(self.extras),
        }


_new = object.__new__
_setattr = object.__setattr__


def _fast_estimate(
    method: str,
    k: int,
    K: float,
    tau: float,
    W: tuple[float, ...],
    valid: bool,
    extras: Mapping[str, Any],
) -> Estimate:
    # The dataclass __init__ costs ~2 µs through object.__setattr__ per field;
    # the per-sample path gives the instance its dict in one go (same object).
    est = _new(Estimate)
    _setattr(
        est,
        "__dict__",
        {
            "method": method,
            "k": k,
            "K": K,
            "tau": tau,
            "W": W,
            "valid": valid,
            "final": False,
            "extras": extras,
        },
    )
    return est


def _first_order_estimate(method: str, k: int, a: float, b: float, dt: float) -> Estimate:
    """Eq. 4 backwards for one estimate, with the same operations as the batch conversion."""
    if 0.0 < a < 1.0 and b - b == 0.0:  # b - b is 0 for finite b only
        return _fast_estimate(method, k, b / (1.0 - a), -dt / math.log(a), (a, b), True, _NO_EXTRAS)
    if not (math.isfinite(a) and math.isfinite(b)):
        code = NON_FINITE
    elif a >= 1.0:
        code = UNSTABLE
    else:
        code = NON_POSITIVE_POLE
    return _fast_estimate(method, k, math.nan, math.nan, (a, b), False, _REASON_EXTRAS[code])


def _general_estimate(method: str, k: int, W: FloatArray, dt: float, order: ArxOrder) -> Estimate:
    K, tau, code = discrete_to_first_order(W[None, :], dt, order)
    c = int(code[0])
    return _fast_estimate(
        method, k, float(K[0]), float(tau[0]), tuple(W.tolist()), c == 0, _REASON_EXTRAS[c]
    )


def _invalid(method: str, k: int, reason: str, *, final: bool = True) -> Estimate:
    return Estimate(method, k, math.nan, math.nan, (), False, final, {"reason": reason})


class OnlineIdentifier:
    """Base of the online identifiers; build one with :func:`make_identifier`.

    Attributes
    ----------
    method : str
        The method's name.
    dt : float
        Sample period in seconds.
    params : dict
        The method's settings, validated and JSON-safe.

    Examples
    --------
    >>> ident = make_identifier("wlsm", 1.0, gamma=0.96, pmax=1e4, w0=[0.96329, 9.9082e-4])
    >>> first = ident.update(5.0, 0.0)
    >>> first.k, round(first.tau, 5), first.final
    (0, 26.73742, False)
    >>> ident.finish().final, ident.n_samples
    (True, 1)
    """

    method: ClassVar[str] = ""

    @classmethod
    def from_settings(cls, dt: float, settings: dict[str, Any]) -> OnlineIdentifier:
        """An identifier from settings checked by :func:`~thermolab.ident.registry.check_settings`.

        Each method checks here what depends on several settings together
        (a window long enough for the order, ``p0`` only with the standard form).
        """
        return cls(dt, settings)

    def __init__(self, dt: float, params: dict[str, Any]) -> None:
        self.dt = dt
        self.params = params
        self._u = np.empty(1024)
        self._y = np.empty(1024)
        self._n = 0
        self._finished = False
        self._final: Estimate | None = None
        self._latest: Estimate | None = None

    @property
    def n_samples(self) -> int:
        """Samples received so far."""
        return self._n

    @property
    def latest(self) -> Estimate | None:
        """The most recent estimate returned (None before the first)."""
        return self._latest

    @property
    def finished(self) -> bool:
        """True once :meth:`finish` has been called."""
        return self._finished

    def update(self, u: float, y: float) -> Estimate | None:
        """Take the next sample: the input applied and the output read at sample ``k``.

        Parameters
        ----------
        u, y : float
            Input and output in absolute volts (``y[k]`` read before ``u[k]``
            is applied, the record convention of :mod:`thermolab.simulation`).

        Returns
        -------
        Estimate or None
            The estimate this sample made available, if any.

        Raises
        ------
        InvalidDataError
            If ``u`` or ``y`` is not a finite number.
        IdentifierStateError
            After :meth:`finish`.
        """
        uf, yf = self._checked_sample(u, y)
        k = self._n
        if k == self._u.size:
            self._grow()
        self._u[k] = uf
        self._y[k] = yf
        self._n = k + 1
        est = self._on_sample(k, uf, yf)
        if est is not None:
            self._latest = est
        return est

    def finish(self) -> Estimate | None:
        """Close the test (the paper's END) and return the final estimate.

        Calling it again returns the same estimate. A record the method cannot
        use (too short, not excited) gives an invalid estimate whose
        ``extras["reason"]`` is the error message, not an exception.

        Returns
        -------
        Estimate or None
            ``final=True``; None when no sample (or no full window/block) arrived.
        """
        if not self._finished:
            self._finished = True
            est = self._on_finish()
            if est is not None:
                est = dataclasses.replace(est, final=True)
                self._latest = est
            self._final = est
        return self._final

    def trajectory(self) -> Trajectory:
        """The estimates so far as a :class:`~thermolab.ident.Trajectory` (one row per sample).

        Raises
        ------
        IdentifierStateError
            For ``srm``, which has one final estimate and no parameter trajectory.
        """
        raise IdentifierStateError(
            f"{self.method} gives one final estimate, not a parameter trajectory"
        )

    def to_dict(self) -> dict[str, Any]:
        """``{"method", "dt", "params", "n_samples", "finished", "latest"}``, JSON-safe."""
        return {
            "method": self.method,
            "dt": self.dt,
            "params": json_safe(self.params),
            "n_samples": self._n,
            "finished": self._finished,
            "latest": self._latest.to_dict() if self._latest is not None else None,
        }

    # -- for subclasses --------------------------------------------------------------

    def _checked_sample(self, u: float, y: float) -> tuple[float, float]:
        # Shared by every update(): a sample is refused before it touches any state.
        if self._finished:
            raise IdentifierStateError(
                f"{self.method}: update() after finish(); make a new identifier for a new run"
            )
        try:
            uf = float(u)
            yf = float(y)
        except (TypeError, ValueError):
            raise InvalidDataError(
                f"sample {self._n}: u and y must be numbers, got u={u!r}, y={y!r}"
            ) from None
        if not (math.isfinite(uf) and math.isfinite(yf)):
            raise InvalidDataError(
                f"sample {self._n}: u and y must be finite, got u={uf!r}, y={yf!r}"
            )
        return uf, yf

    def _grow(self) -> None:
        size = 2 * self._u.size
        for name in self._growing():
            old = getattr(self, name)
            new = np.empty((size, *old.shape[1:]), dtype=old.dtype, order="F")
            new[: self._n] = old[: self._n]
            setattr(self, name, new)

    def _growing(self) -> tuple[str, ...]:
        return ("_u", "_y")

    def _record(self) -> tuple[FloatArray, FloatArray]:
        return self._u[: self._n], self._y[: self._n]

    def _on_sample(self, k: int, u: float, y: float) -> Estimate | None:
        return None

    def _on_finish(self) -> Estimate | None:
        return self._latest


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
        valid = math.isfinite(res.K) and math.isfinite(res.tau)
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
        from .output_error import output_error

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


class _Recursive(OnlineIdentifier):
    """Shared machinery of MALSM and WLSM: the shifted record and the kernels' outputs.

    The per-sample path is kept short (a few microseconds): one compiled kernel
    call on preallocated arrays, which for first order also returns the new
    ``(status, a, b)``, and an :class:`Estimate` filled without ``__init__``.
    """

    def __init__(self, dt: float, params: dict[str, Any], order: ArxOrder, offset: str | float):
        super().__init__(dt, params)
        from . import _kernels

        self._k = _kernels
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
            status, a, b = self._k.malsm2_chunk(
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
            status, a, b = self._k.wlsm2_chunk(
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


@overload
def _model(
    settings: dict[str, Any], *, search: Literal[False] = False
) -> tuple[ArxOrder, str | float, dict[str, Any]]: ...
@overload
def _model(
    settings: dict[str, Any], *, search: Literal[True]
) -> tuple[ArxOrder | None, str | float, dict[str, Any]]: ...
def _model(
    settings: dict[str, Any], *, search: bool = False
) -> tuple[ArxOrder | None, str | float, dict[str, Any]]:
    """The checked order and offset, and their JSON-ready form for ``params``.

    An order not given is the paper's first order, except where the method
    searches the dead time (``search``: LSM), which keeps None (``params``
    shows ``None``: searched at END).
    """
    given = settings["order"]
    order = None if given is None and search else _v.check_order(given)
    offset = _v.check_offset_or_auto(settings["offset"])
    shown = None if order is None else order.to_dict()
    common = {"order": shown, "offset": offset}
    if "expected_sign" in settings:
        common["expected_sign"] = settings["expected_sign"]
    return order, offset, common


def _n_params(order: ArxOrder, offset: str | float) -> int:
    return order.na + order.nb + int(offset == "fit")


def _with_trust(est: Estimate, tr: Trajectory) -> Estimate:
    """The final estimate with the END trajectory's row, warnings and operating point.

    When END decided another operating point than the live estimates used, the
    row of the END trajectory replaces the live estimate.
    """
    k = est.k
    if tr.n_samples > k and tr.W.shape[1] and not np.array_equal(tr.W[k], np.asarray(est.W)):
        ok = bool(tr.valid[k])
        est = Estimate(
            est.method, k, float(tr.K[k]), float(tr.tau[k]), tuple(tr.W[k].tolist()), ok,
            est.final, _NO_EXTRAS if ok else {"reason": tr.invalid_reason[k]},
        )  # fmt: skip
    extras = {
        **est.extras,
        "theta": tr.order.delay * tr.dt,
        "offset": tr.offset,
        "operating_point": None if tr.operating_point is None else tr.operating_point.to_dict(),
        "warnings": list(tr.warnings),
        "trusted": est.valid and not tr.warnings,
    }
    return dataclasses.replace(est, extras=extras)


def make_identifier(method: str, dt: float, **params: Any) -> OnlineIdentifier:
    """An online identifier for ``method``, its settings checked now rather than at END.

    Parameters
    ----------
    method : {"srm", "lsm", "blockls", "malsm", "wlsm"}
        The identification method.
    dt : float
        Sample period in seconds, > 0.
    **params
        The method's settings, as declared in :mod:`thermolab.ident.registry`
        (names, defaults, ranges; those with ``role="identify"``):

        * ``srm``: ``u_initial``, ``min_step``, ``min_samples``, ``settle_time_constants``;
        * ``lsm``: ``order``, ``offset``;
        * ``blockls``: ``block``, ``order``, ``offset``;
        * ``malsm``: ``window``, ``recompute_every``, ``order``, ``offset``;
        * ``wlsm``: ``gamma``, ``pmax``, ``w0``, ``form``, ``p0``, ``order``, ``offset``.

        ``order`` may be an :class:`~thermolab.ident.ArxOrder`, a ``(na, nb,
        delay)`` tuple or a ``{"na", "nb", "delay"}`` dict (from JSON).

    Returns
    -------
    OnlineIdentifier

    Raises
    ------
    InvalidParameterError
        For an unknown method or parameter (the message lists the allowed ones),
        or a parameter out of range.

    Examples
    --------
    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL
    >>> u = np.where((np.arange(300) // 5) % 2 == 0, 6.0, 4.0)
    >>> y = REFERENCE_MODEL.simulate(u)
    >>> ident = make_identifier("malsm", 1.0, window=100)
    >>> estimates = [ident.update(uk, yk) for uk, yk in zip(u, y)]
    >>> estimates[98] is None, estimates[99].k
    (True, 99)
    >>> print(round(estimates[-1].K, 6), round(estimates[-1].tau, 6))
    0.14009 250.126233
    """
    online = get_method(method).online_class()
    step = _v.check_dt(dt)
    identifier: OnlineIdentifier = online.from_settings(step, check_settings(method, params))
    return identifier
