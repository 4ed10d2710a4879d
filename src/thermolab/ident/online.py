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
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Literal, overload

import numpy as np
import numpy.typing as npt

from thermolab.errors import (
    IdentifierStateError,
    InvalidDataError,
)
from thermolab.jsonsafe import json_safe

from . import _validation as _v
from .models import (
    INVALID_REASONS,
    NON_FINITE,
    NON_POSITIVE_POLE,
    UNSTABLE,
    ArxOrder,
    discrete_to_first_order,
)
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
    if "max_delay" in settings:
        # Live, the block and recursive methods take the order given (no search).
        common["max_delay"] = settings["max_delay"]
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
