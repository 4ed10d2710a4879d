"""Exact discrete simulation of the paper's plant (eq. 4) and of general ARX models.

The paper's plant is first order, ``Ks / (Ts s + 1)``; sampled with period ``T``
behind a zero-order hold it is exactly (eq. 4)

    v0(k+1) = a v0(k) + b vi(k),   a = exp(-T/Ts),   b = (1 - a) Ks.

:func:`simulate_first_order` evaluates this recursion (with an optional ambient
operating point), :func:`simulate_arx` a general ARX recursion, and
:data:`REFERENCE_MODEL` is the paper's reference model (eq. 16). Both
simulations run the recursion through :func:`scipy.signal.lfilter`, a compiled
IIR filter, so a million samples take milliseconds.

Record convention (all functions): ``y[k]`` is the output *read* at sample
``k``, before the input ``u[k]`` is applied, so ``u[k]`` first shows in
``y[k+1]`` and the last input sample has no effect on the returned record. This
is how a sampled rig behaves and how the identification methods regress
(``Y(k) = y[k+1]`` on ``D(k) = [y[k], u[k]]``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.
from thermolab.errors import InvalidDataError, InvalidParameterError

__all__ = [
    "PAPER_W0",
    "REFERENCE_MODEL",
    "FirstOrderPlant",
    "simulate_arx",
    "simulate_first_order",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class FirstOrderPlant:
    """A first-order plant ``K / (tau s + 1)`` sampled every ``dt`` seconds.

    Parameters
    ----------
    K : float
        Static gain (output volts per input volt), any finite non-zero value.
    tau : float
        Time constant in seconds, finite and > 0.
    dt : float
        Sample period in seconds, finite and > 0.

    Raises
    ------
    InvalidParameterError
        If a parameter is not finite, ``K`` is zero, or ``tau`` or ``dt`` is not positive.

    Notes
    -----
    A plain parameter record for simulations; the identification results live in
    :mod:`thermolab.ident`, which this numerics module does not import.

    Examples
    --------
    >>> plant = FirstOrderPlant(K=2.0, tau=10.0, dt=1.0)
    >>> round(plant.a, 6), round(plant.b, 6)
    (0.904837, 0.190325)
    """

    K: float
    tau: float
    dt: float

    def __post_init__(self) -> None:
        _check_first_order(self.K, self.tau, self.dt)

    @property
    def a(self) -> float:
        """Discrete pole ``exp(-dt/tau)`` of eq. 4."""
        return math.exp(-self.dt / self.tau)

    @property
    def b(self) -> float:
        """Discrete input coefficient ``(1 - a) K`` of eq. 4."""
        return -math.expm1(-self.dt / self.tau) * self.K

    @property
    def w(self) -> tuple[float, float]:
        """The paper's parameter vector ``W = [a, b]``."""
        return (self.a, self.b)

    def simulate(
        self, u: npt.ArrayLike, *, y0: float | None = None, ambient: float = 0.0
    ) -> FloatArray:
        """Simulate this plant; see :func:`simulate_first_order`.

        Parameters
        ----------
        u : array_like
            Input samples (volts).
        y0 : float or None, optional
            First output sample; ``None`` starts at rest at ``ambient``.
        ambient : float, optional
            Output at rest with zero input (the operating point).

        Returns
        -------
        numpy.ndarray
            The output record, same length as ``u``.

        Examples
        --------
        >>> FirstOrderPlant(K=1.0, tau=1.0, dt=1.0).simulate([1.0, 1.0, 1.0]).round(4)
        array([0.    , 0.6321, 0.8647])
        """
        return simulate_first_order(u, self.K, self.tau, self.dt, y0=y0, ambient=ambient)


def simulate_first_order(
    u: npt.ArrayLike,
    K: float,
    tau: float,
    dt: float,
    *,
    y0: float | None = None,
    ambient: float = 0.0,
    theta: float = 0.0,
) -> FloatArray:
    """Simulate eq. 4 exactly: ``y(k+1) - c = a (y(k) - c) + b u(k)``, ``c`` the ambient.

    With a dead time ``theta`` the plant is ``K exp(-theta s) / (tau s + 1)``.

    Parameters
    ----------
    u : array_like
        Input samples in volts, one-dimensional, finite, at least one sample.
    K : float
        Static gain (volts per volt), finite and non-zero.
    tau : float
        Time constant in seconds, finite and > 0.
    dt : float
        Sample period in seconds, finite and > 0.
    y0 : float or None, optional
        The first output sample ``y[0]``. ``None`` (default) starts the plant at
        rest at ``ambient``.
    ambient : float, optional
        Output at rest with zero input: the operating point (ambient temperature
        reading). Default 0, the paper's simulations.
    theta : float, optional
        Dead time (transport delay) in seconds, finite and >= 0, any value (not
        only whole samples). Default 0. Before the record the plant is settled:
        the input was 0 (``y0`` None) or the one that holds ``y0``.

    Returns
    -------
    numpy.ndarray
        ``y`` with ``len(u)`` samples; ``y[k]`` is read before ``u[k]`` is applied,
        so ``y[k+1]`` is the first sample that shows ``u[k]``.

    Raises
    ------
    InvalidDataError
        If ``u`` is empty, not one-dimensional or not finite.
    InvalidParameterError
        If ``K``, ``tau``, ``dt``, ``y0`` or ``ambient`` is out of range.

    Notes
    -----
    The recursion is run by :func:`scipy.signal.lfilter` with the filter state
    set to the initial deviation from ambient, so it is the exact
    zero-order-hold discretisation, not an ODE integration: for a 0→U step at
    ``k = 0`` the output is ``K U (1 - a**k)`` to rounding.

    With dead time, a delay of ``d`` whole samples plus a fraction ``phi`` of one
    splits each held input over two samples (exact behind the zero-order hold):
    ``y(k+1) - c = a (y(k) - c) + b1 u(k-d) + b2 u(k-d-1)`` with
    ``b1 = K (1 - exp(-(dt - phi)/tau))`` and ``b2 = K (exp(-(dt - phi)/tau) - a)``.
    (:mod:`thermolab.ident` states the same model for its fits; the two layers
    are independent by contract, so neither imports the other.)

    Examples
    --------
    The paper's 0→10 V step on the reference model, after 2000 samples:

    >>> import numpy as np
    >>> y = simulate_first_order(np.full(2001, 10.0), K=0.140090, tau=250.126233, dt=1.0)
    >>> round(float(y[2000]) / 10, 7)
    0.1400428

    Starting from a warm ambient of 2.5 V with the input off, nothing moves:

    >>> simulate_first_order(np.zeros(3), K=0.14, tau=250.0, dt=1.0, ambient=2.5)
    array([2.5, 2.5, 2.5])

    Two seconds of dead time hold the answer back two samples:

    >>> simulate_first_order(np.ones(5), K=1.0, tau=1.0, dt=1.0, theta=2.0).round(4)
    array([0.    , 0.    , 0.    , 0.6321, 0.8647])
    """
    _check_first_order(K, tau, dt)
    u_arr = _as_input(u)
    ambient_v = _finite("ambient", ambient)
    theta_v = _finite("theta", theta)
    if theta_v < 0.0:
        raise InvalidParameterError(f"theta (dead time) must be >= 0 seconds, got {theta_v!r}")
    x0 = 0.0 if y0 is None else _finite("y0", y0) - ambient_v
    a = math.exp(-dt / tau)
    if theta_v > 0.0:
        return _simulate_delayed(u_arr, K, tau, dt, theta_v, x0) + ambient_v
    b = -math.expm1(-dt / tau) * K
    # y[k] = b u[k-1] + a y[k-1] with the filter's single state holding y[0].
    from scipy.signal import lfilter

    deviation: FloatArray = lfilter([0.0, b], [1.0, -a], u_arr, zi=[x0])[0]
    return deviation + ambient_v


def simulate_arx(
    u: npt.ArrayLike,
    a: Sequence[float],
    b: Sequence[float],
    *,
    delay: int = 0,
    y0: float | None = None,
    ambient: float = 0.0,
) -> FloatArray:
    """Simulate an ARX model without noise.

    ``y[k] - c = sum_i a[i] (y[k-1-i] - c) + sum_j b[j] u[k-1-delay-j]``, with ``c``
    the ambient, ``i = 0 .. na-1`` and ``j = 0 .. nb-1``.

    Parameters
    ----------
    u : array_like
        Input samples in volts, one-dimensional, finite, at least one sample.
    a : sequence of float
        Output coefficients ``a_1 .. a_na`` in the paper's sign (eq. 4 is ``a = [a]``);
        may be empty (a finite-impulse-response model).
    b : sequence of float
        Input coefficients ``b_1 .. b_nb`` (at least one).
    delay : int, optional
        Dead time in samples *beyond* the one sample every plant sampled behind a
        zero-order hold has, >= 0 (default 0: eq. 4, where ``u[k]`` first shows in
        ``y[k+1]``). The same convention as :class:`thermolab.ident.ArxOrder`.
    y0 : float or None, optional
        Output before and at ``k = 0``: ``y[k] = y0`` for ``k <= 0``. ``None`` (default)
        starts at rest at ``ambient``.
    ambient : float, optional
        The operating point the model's deviations are taken from. Default 0.

    Returns
    -------
    numpy.ndarray
        ``y`` with ``len(u)`` samples; inputs before ``k = 0`` are taken as zero.

    Raises
    ------
    InvalidDataError
        If ``u`` is empty, not one-dimensional or not finite.
    InvalidParameterError
        If a coefficient is not finite, ``b`` is empty, or ``delay`` < 0.

    Notes
    -----
    The model may be unstable; the output then grows without bound, as it would.
    With ``a = [exp(-dt/tau)]``, ``b = [(1 - a) K]`` and ``delay = 0`` this equals
    :func:`simulate_first_order`.

    Examples
    --------
    >>> simulate_arx([1.0, 1.0, 1.0, 1.0], a=[0.5], b=[1.0])
    array([0.  , 1.  , 1.5 , 1.75])
    >>> simulate_arx([1.0, 0.0, 0.0, 0.0], a=[], b=[1.0, 2.0], delay=1)
    array([0., 0., 1., 2.])
    """
    u_arr = _as_input(u)
    a_arr = np.array([_finite(f"a[{i}]", v) for i, v in enumerate(a)], dtype=np.float64)
    b_arr = np.array([_finite(f"b[{j}]", v) for j, v in enumerate(b)], dtype=np.float64)
    if b_arr.size == 0:
        raise InvalidParameterError("b must hold at least one input coefficient, got none")
    if isinstance(delay, bool) or not isinstance(delay, int | np.integer) or delay < 0:
        raise InvalidParameterError(
            f"delay must be an integer >= 0 (samples beyond the natural one), got {delay!r}"
        )
    ambient_v = _finite("ambient", ambient)
    x0 = 0.0 if y0 is None else _finite("y0", y0) - ambient_v
    n = u_arr.size
    # Filter the shifted output w[m] = y[m+1] - c driven by u[m]: its numerator is b
    # delayed by `delay` samples, and its past outputs are y[0], y[-1], ... = y0.
    num = np.concatenate([np.zeros(int(delay)), b_arr])
    den = np.concatenate([[1.0], -a_arr])
    past_w = np.full(max(a_arr.size, 1), x0)
    from scipy.signal import lfilter, lfiltic

    zi = lfiltic(num, den, past_w, np.zeros(max(num.size - 1, 1)))
    w: FloatArray = lfilter(num, den, u_arr[: n - 1], zi=zi)[0] if n > 1 else np.empty(0)
    return np.concatenate([[x0], w]) + ambient_v


def _simulate_delayed(
    u: FloatArray, K: float, tau: float, dt: float, theta: float, x0: float
) -> FloatArray:
    """Deviation from ambient of a first-order lag plus dead time, settled before ``u``."""
    d = int(theta // dt)
    phi = theta - d * dt
    a = math.exp(-dt / tau)
    rest = math.exp(-(dt - phi) / tau)
    b1, b2 = K * (1.0 - rest), K * (rest - a)
    u_past = x0 / K  # the input that held the plant settled at x0
    held = np.concatenate([np.full(d + 1, u_past), u])
    n = u.size
    # drive[k] = b1 u[k-d] + b2 u[k-d-1], for k = 0 .. n-2.
    drive = b1 * held[1:n] + b2 * held[: n - 1]
    if n == 1:
        return np.array([x0])
    from scipy.signal import lfilter

    rest_of: FloatArray = lfilter([1.0], [1.0, -a], drive, zi=[a * x0])[0]
    return np.concatenate([[x0], rest_of])


def _check_first_order(K: float, tau: float, dt: float) -> None:
    K_v = _finite("K", K)
    if K_v == 0.0:
        raise InvalidParameterError("K (static gain) must be non-zero, got 0")
    if not _finite("tau", tau) > 0.0:
        raise InvalidParameterError(f"tau (time constant) must be > 0 seconds, got {tau!r}")
    if not _finite("dt", dt) > 0.0:
        raise InvalidParameterError(f"dt (sample period) must be > 0 seconds, got {dt!r}")


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InvalidParameterError(f"{name} must be finite, got {v!r}")
    return v


def _as_input(u: npt.ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(u, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidDataError(f"u must be an array of numbers: {exc}") from None
    if arr.ndim != 1:
        raise InvalidDataError(f"u must be one-dimensional, got shape {arr.shape}")
    if arr.size == 0:
        raise InvalidDataError("u is empty: give at least one input sample")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise InvalidDataError(
            f"u must be finite; u[{bad[0]}] is {float(arr[bad[0]])!r} ({bad.size} bad samples)"
        )
    return arr


#: The paper's reference model (eq. 16), identified on the real rig by the step method.
REFERENCE_MODEL = FirstOrderPlant(K=0.140090, tau=250.126233, dt=1.0)

#: The paper's initial parameters for WLSM, ``W0 = [a, b]`` (Ks = 0.0269905, Ts = 26.73742 s).
PAPER_W0: tuple[float, float] = (0.96329, 9.9082e-4)
