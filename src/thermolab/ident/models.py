"""Model structures and the conversion between discrete parameters and (K, tau).

The paper identifies the discrete first-order model of eq. 4,

    y[k+1] = a y[k] + b u[k],    a = exp(-dt/tau),    b = (1 - a) K,

and reports the continuous gain ``K`` and time constant ``tau``. The way back,
``tau = -dt / ln(a)`` and ``K = b / (1 - a)``, only means something for
``0 < a < 1``; this module gives a result that *says* so for every other ``a``
(an unstable or integrating model, a sign-alternating one, a diverged estimate)
instead of raising from deep inside or returning a silent NaN.

A general ARX order (:class:`ArxOrder`) uses the same positive sign convention:

    y[k+1] = a1 y[k] + ... + a_na y[k-na+1]
             + b1 u[k-delay] + ... + b_nb u[k-delay-nb+1]  (+ c)

so that first order with no delay is exactly eq. 4 and ``W = [a, b]``. For any
order, ``K`` is the DC gain ``sum(b) / (1 - sum(a))`` and ``tau`` the time
constant of the dominant pole, which must be real and in (0, 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none

from .notes import note

__all__ = [
    "FIRST_ORDER",
    "INVALID_REASONS",
    "ArxOrder",
    "FirstOrderModel",
    "discrete_to_first_order",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int8]

# Reason codes shared by every trajectory (index into INVALID_REASONS).
VALID = 0
NO_ESTIMATE = 1
NOT_EXCITED = 2
UNSTABLE = 3
NON_POSITIVE_POLE = 4
COMPLEX_POLE = 5
NON_FINITE = 6

#: Why an estimate has no first-order meaning, indexed by ``Trajectory.reason_code``.
INVALID_REASONS: tuple[str | None, ...] = (
    None,
    note("no_estimate_yet"),
    note("not_excited"),
    note("unstable"),
    note("non_positive_pole"),
    note("complex_pole"),
    note("non_finite"),
)


def _check_int(name: str, value: object, minimum: int, maximum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidParameterError(f"{name} must be an integer, got {value!r}")
    v = int(value)
    if not minimum <= v <= maximum:
        raise InvalidParameterError(f"{name} must be between {minimum} and {maximum}, got {v}")
    return v


def _check_real(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a real number, got {value!r}")
    return float(value)


def _check_dt(dt: object) -> float:
    v = _check_real("dt", dt)
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidParameterError(f"dt (sample period) must be finite and > 0 seconds, got {v!r}")
    return v


@dataclass(frozen=True)
class ArxOrder:
    """The structure of an ARX model: ``na`` output lags, ``nb`` input lags, a dead time.

    ``y[k+1] = a1 y[k] + ... + a_na y[k-na+1] + b1 u[k-delay] + ... + b_nb u[k-delay-nb+1]``.

    Parameters
    ----------
    na : int, optional
        Number of past outputs (1 to 10). Default 1.
    nb : int, optional
        Number of past inputs (1 to 10). Default 1.
    delay : int, optional
        Dead time in samples *beyond* the one sample every sampled plant has
        (0 to 1000). Default 0: ``u[k]`` first shows in ``y[k+1]``, as in eq. 4.
        :func:`thermolab.simulation.simulate_arx` takes the same convention.

    Raises
    ------
    InvalidParameterError
        If a value is not an integer in its range.

    Examples
    --------
    >>> ArxOrder()
    ArxOrder(na=1, nb=1, delay=0)
    >>> ArxOrder(2, 2, 3).lag, ArxOrder(2, 2, 3).param_names()
    (4, ('a1', 'a2', 'b1', 'b2'))
    """

    na: int = 1
    nb: int = 1
    delay: int = 0

    def __post_init__(self) -> None:
        _check_int("na (number of output lags)", self.na, 1, 10)
        _check_int("nb (number of input lags)", self.nb, 1, 10)
        _check_int("delay (dead time in samples)", self.delay, 0, 1000)

    @property
    def lag(self) -> int:
        """Index of the first sample that can be a regressor row's newest sample.

        Row ``k`` regresses ``y[k+1]`` on samples back to ``k - lag``; the first
        usable ``k`` is ``lag``.
        """
        return max(self.na - 1, self.delay + self.nb - 1)

    @property
    def is_first_order(self) -> bool:
        """True for eq. 4's structure (``na = nb = 1``, no dead time)."""
        return self.na == 1 and self.nb == 1 and self.delay == 0

    def param_names(self, *, constant: bool = False) -> tuple[str, ...]:
        """Names of the entries of ``W``, in order.

        Parameters
        ----------
        constant : bool, optional
            Append ``"c"``, the constant term of ``offset="fit"``.

        Returns
        -------
        tuple of str
            ``("a", "b")`` for first order, else ``("a1", ..., "b1", ...)``.

        Examples
        --------
        >>> ArxOrder().param_names(constant=True)
        ('a', 'b', 'c')
        """
        if self.is_first_order:
            names: tuple[str, ...] = ("a", "b")
        else:
            names = tuple(f"a{i + 1}" for i in range(self.na)) + tuple(
                f"b{j + 1}" for j in range(self.nb)
            )
        return (*names, "c") if constant else names

    def to_dict(self) -> dict[str, int]:
        """``{"na", "nb", "delay"}``."""
        return {"na": self.na, "nb": self.nb, "delay": self.delay}


#: Eq. 4's structure: ``y[k+1] = a y[k] + b u[k]``.
FIRST_ORDER = ArxOrder()


@dataclass(frozen=True)
class FirstOrderModel:
    """A first-order lag plus dead time ``K exp(-theta s) / (tau s + 1)``, or why it is not one.

    Parameters
    ----------
    K : float
        Static gain (output volts per input volt). NaN when ``reason`` is set.
    tau : float
        Time constant in seconds, > 0. NaN when ``reason`` is set.
    reason : str or None, optional
        Why the model has no first-order meaning (``None``: it has one). Set by
        :meth:`from_discrete`; leave it out when building a model by hand.
    theta : float, optional
        Dead time (transport delay) in seconds, >= 0. Default 0: the paper's
        first-order model. A sampled model with ``delay`` samples of dead time
        beyond the natural one (:class:`ArxOrder`) has ``theta = delay * dt``.

    Raises
    ------
    InvalidParameterError
        If ``reason`` is None and ``K`` is not finite, ``tau`` is not finite and > 0,
        or ``theta`` is not finite and >= 0.

    Examples
    --------
    >>> m = FirstOrderModel(K=0.140090, tau=250.126233)
    >>> a, b = m.to_discrete(1.0)
    >>> round(a, 9), round(b, 9)
    (0.99601, 0.000558959)
    >>> back = FirstOrderModel.from_discrete(a, b, 1.0)
    >>> round(back.K, 6), round(back.tau, 6)
    (0.14009, 250.126233)
    >>> bad = FirstOrderModel.from_discrete(1.003, 0.001, 1.0)
    >>> bad.valid
    False
    >>> bad.reason
    'a = 1.003 >= 1: the identified model is unstable or integrating and has no time constant'
    """

    K: float
    tau: float
    reason: str | None = None
    theta: float = 0.0

    def __post_init__(self) -> None:
        K = _check_real("K", self.K)
        tau = _check_real("tau", self.tau)
        theta = _check_real("theta", self.theta)
        if not (math.isfinite(theta) and theta >= 0.0):
            raise InvalidParameterError(
                f"theta (dead time) must be finite and >= 0 seconds, got {theta!r}"
            )
        if self.reason is None:
            if not math.isfinite(K):
                raise InvalidParameterError(f"K (static gain) must be finite, got {K!r}")
            if not (math.isfinite(tau) and tau > 0.0):
                raise InvalidParameterError(
                    f"tau (time constant) must be finite and > 0 seconds, got {tau!r}"
                )

    @property
    def valid(self) -> bool:
        """True when the model is a genuine first-order lag."""
        return self.reason is None

    def to_discrete(self, dt: float) -> tuple[float, float]:
        """The exact zero-order-hold discretisation (eq. 4).

        Parameters
        ----------
        dt : float
            Sample period in seconds, > 0.

        Returns
        -------
        (a, b) : tuple of float
            ``a = exp(-dt/tau)``, ``b = (1 - a) K``.

        Raises
        ------
        InvalidParameterError
            If ``dt`` is not > 0, or the model is not valid (the message gives its reason).

        Examples
        --------
        >>> FirstOrderModel(2.0, 10.0).to_discrete(1.0)  # doctest: +NUMBER
        (0.904837, 0.190325)
        """
        step = _check_dt(dt)
        if self.reason is not None:
            raise InvalidParameterError(f"this model has no discretisation: {self.reason}")
        a = math.exp(-step / self.tau)
        return a, -math.expm1(-step / self.tau) * self.K

    @classmethod
    def from_discrete(cls, a: float, b: float, dt: float) -> FirstOrderModel:
        """Convert eq. 4's ``(a, b)`` to ``(K, tau)``, or say why that is impossible.

        Parameters
        ----------
        a, b : float
            Discrete pole and input coefficient.
        dt : float
            Sample period in seconds, > 0.

        Returns
        -------
        FirstOrderModel
            Valid when ``0 < a < 1`` and both are finite; otherwise ``K`` and
            ``tau`` are NaN and ``reason`` names the problem with the value of ``a``.

        Raises
        ------
        InvalidParameterError
            If ``dt`` is not finite and > 0 (a bad argument, not a bad model).

        Examples
        --------
        >>> FirstOrderModel.from_discrete(-0.2, 0.5, 1.0).reason
        'a = -0.2 <= 0: a sampled first-order lag has 0 < a < 1; this model has no time constant'
        """
        step = _check_dt(dt)
        a_v = _check_real("a", a)
        b_v = _check_real("b", b)
        reason = _first_order_reason(a_v, b_v)
        if reason is not None:
            return cls(math.nan, math.nan, reason)
        return cls(b_v / (1.0 - a_v), -step / math.log(a_v))

    def with_dead_time(self, theta: float) -> FirstOrderModel:
        """The same lag with dead time ``theta`` seconds.

        Examples
        --------
        >>> FirstOrderModel(2.0, 10.0).with_dead_time(3.0).theta
        3.0
        """
        return FirstOrderModel(self.K, self.tau, self.reason, theta)

    def to_dict(self) -> dict[str, Any]:
        """``{"K", "tau", "theta", "valid", "reason"}`` (NaN as ``None``, JSON-safe)."""
        return {
            "K": finite_or_none(self.K),
            "tau": finite_or_none(self.tau),
            "theta": finite_or_none(self.theta),
            "valid": self.valid,
            "reason": self.reason,
        }


def _first_order_reason(a: float, b: float) -> str | None:
    if not (math.isfinite(a) and math.isfinite(b)):
        return f"a = {a:.6g}, b = {b:.6g}: the estimate is not finite (it diverged or overflowed)"
    if a >= 1.0:
        return (
            f"a = {a:.6g} >= 1: the identified model is unstable or integrating "
            "and has no time constant"
        )
    if a <= 0.0:
        return (
            f"a = {a:.6g} <= 0: a sampled first-order lag has 0 < a < 1; "
            "this model has no time constant"
        )
    return None


def discrete_to_first_order(
    W: npt.ArrayLike, dt: float, order: ArxOrder | None = None
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Vectorised ``W -> (K, tau)`` for a whole trajectory of estimates.

    Parameters
    ----------
    W : array_like, shape (n, n_params) or (n_params,)
        Parameter vectors ``[a1..a_na, b1..b_nb]`` (a trailing constant ``c``,
        if present, is ignored). Rows of NaN are "no estimate".
    dt : float
        Sample period in seconds, > 0.
    order : ArxOrder, optional
        The structure of ``W``; default first order (``W = [a, b]``).

    Returns
    -------
    K, tau : numpy.ndarray of float, shape (n,)
        DC gain and dominant time constant; NaN where the row has no first-order meaning.
    code : numpy.ndarray of int8, shape (n,)
        0 where valid, else the index of the reason in :data:`INVALID_REASONS`.

    Raises
    ------
    InvalidParameterError
        If ``dt`` is not > 0 or ``W`` has fewer columns than the order needs.

    Examples
    --------
    >>> import numpy as np
    >>> K, tau, code = discrete_to_first_order([[0.9, 0.2], [1.01, 0.1], [np.nan, np.nan]], 1.0)
    >>> K.round(6), tau.round(6), code
    (array([ 2., nan, nan]), array([9.491222,      nan,      nan]), array([0, 3, 1], dtype=int8))
    """
    step = _check_dt(dt)
    ord_ = FIRST_ORDER if order is None else order
    arr = np.asarray(W, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    n_dyn = ord_.na + ord_.nb
    if arr.ndim != 2 or arr.shape[1] < n_dyn:
        raise InvalidParameterError(
            f"W must have shape (n, >= {n_dyn}) for order {ord_}, got {np.shape(W)}"
        )
    if ord_.na == 1 and ord_.nb == 1:
        return _first_order_arrays(arr[:, 0], arr[:, 1], step)
    a = arr[:, : ord_.na]
    b = arr[:, ord_.na : n_dyn]
    n = arr.shape[0]
    code = np.zeros(n, dtype=np.int8)
    K = np.full(n, np.nan)
    tau = np.full(n, np.nan)
    missing = np.isnan(arr[:, :n_dyn]).all(axis=1)
    finite = np.isfinite(arr[:, :n_dyn]).all(axis=1)
    code[~finite] = NON_FINITE
    code[missing] = NO_ESTIMATE
    if ord_.na == 1:
        pole = a[:, 0].copy()
        pole[~finite] = np.nan
        with np.errstate(invalid="ignore"):
            code[finite & (pole >= 1.0)] = UNSTABLE
            code[finite & (pole <= 0.0)] = NON_POSITIVE_POLE
    else:
        pole = np.full(n, np.nan)
        rows = np.flatnonzero(finite)
        if rows.size:
            comp = np.zeros((rows.size, ord_.na, ord_.na))
            comp[:, 0, :] = a[rows]
            idx = np.arange(ord_.na - 1)
            comp[:, idx + 1, idx] = 1.0
            eig = np.linalg.eigvals(comp)
            mod = np.abs(eig)
            order_idx = np.argsort(-mod, axis=1, kind="stable")
            eig_sorted = np.take_along_axis(eig, order_idx, axis=1)
            mod_sorted = np.take_along_axis(mod, order_idx, axis=1)
            dom = eig_sorted[:, 0]
            rcode = np.zeros(rows.size, dtype=np.int8)
            pair = (mod_sorted[:, 1] == mod_sorted[:, 0]) & (eig_sorted[:, 1] != dom)
            rcode[(dom.imag != 0.0) | pair] = COMPLEX_POLE
            rcode[(rcode == 0) & (dom.real <= 0.0)] = NON_POSITIVE_POLE
            rcode[mod_sorted[:, 0] >= 1.0] = UNSTABLE
            code[rows] = rcode
            pole[rows] = np.where(rcode == 0, dom.real, np.nan)
    ok = code == VALID
    sum_a = a[ok].sum(axis=1)
    sum_b = b[ok].sum(axis=1)
    K[ok] = sum_b / (1.0 - sum_a)
    tau[ok] = -step / np.log(pole[ok])
    return K, tau, code


def _first_order_arrays(
    a: FloatArray, b: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Eq. 4 backwards for whole columns, in a few full-array passes (no fancy indexing)."""
    with np.errstate(all="ignore"):
        K = b / (1.0 - a)
        tau = np.log(a)
        np.divide(-dt, tau, out=tau)
        code = (a >= 1.0).astype(np.int8)  # 1 for now, UNSTABLE below
        code *= UNSTABLE
        code += (a <= 0.0).astype(np.int8) * NON_POSITIVE_POLE
        bad = ~(np.isfinite(a) & np.isfinite(b))
        if bad.any():
            code[bad] = NON_FINITE
            code[np.isnan(a) & np.isnan(b)] = NO_ESTIMATE
    invalid = code != VALID
    np.copyto(K, np.nan, where=invalid)
    np.copyto(tau, np.nan, where=invalid)
    return K, tau, code
