"""The general discrete ARX model: any order, its DC gain and dominant pole.

:class:`ArxModel` holds the coefficients of an :class:`~thermolab.ident.models.ArxOrder`
(the positive sign convention of eq. 4, generalised) and reduces them to the
first-order ``(K, tau)`` the paper reports (:meth:`ArxModel.first_order`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none

from .models import INVALID_REASONS, NON_FINITE, ArxOrder, FirstOrderModel, _check_dt

__all__ = ["ArxModel"]


@dataclass(frozen=True)
class ArxModel:
    """A discrete ARX model in the positive convention of :class:`ArxOrder`.

    Parameters
    ----------
    a : tuple of float
        Output coefficients ``a1 .. a_na`` (at least one).
    b : tuple of float
        Input coefficients ``b1 .. b_nb`` (at least one).
    dt : float
        Sample period in seconds.
    delay : int, optional
        Dead time beyond one sample (see :class:`ArxOrder`). Default 0.
    c : float, optional
        Constant term (``offset="fit"``); 0 otherwise.

    Raises
    ------
    InvalidParameterError
        If a coefficient list is empty, ``dt`` is not > 0 or ``delay`` is out of range.

    Examples
    --------
    >>> m = ArxModel(a=(0.9,), b=(0.2,), dt=1.0, c=0.25)
    >>> round(m.K, 6), round(m.tau, 6), round(m.ambient, 6)
    (2.0, 9.491222, 2.5)
    >>> ArxModel(a=(0.0, -0.25), b=(1.0,), dt=1.0).first_order().reason
    'dominant pole is complex (0+0.5j): the model oscillates and has no first-order time constant'
    """

    a: tuple[float, ...]
    b: tuple[float, ...]
    dt: float
    delay: int = 0
    c: float = 0.0

    def __post_init__(self) -> None:
        if len(self.a) == 0 or len(self.b) == 0:
            raise InvalidParameterError("an ARX model needs at least one a and one b coefficient")
        _check_dt(self.dt)
        ArxOrder(len(self.a), len(self.b), self.delay)

    @property
    def order(self) -> ArxOrder:
        """The model's structure."""
        return ArxOrder(len(self.a), len(self.b), self.delay)

    @property
    def poles(self) -> npt.NDArray[np.complex128]:
        """Roots of ``z**na - a1 z**(na-1) - ... - a_na``, largest modulus first."""
        roots = np.roots(np.concatenate([[1.0], -np.asarray(self.a, dtype=np.float64)]))
        return np.asarray(roots[np.argsort(-np.abs(roots), kind="stable")], dtype=np.complex128)

    @property
    def K(self) -> float:  # noqa: N802 - the paper's symbol
        """DC gain ``sum(b) / (1 - sum(a))`` (NaN when not a first-order-like model)."""
        return self.first_order().K

    @property
    def tau(self) -> float:
        """Time constant of the dominant pole in seconds (NaN when it has none)."""
        return self.first_order().tau

    @property
    def ambient(self) -> float:
        """Equilibrium output at zero input, ``c / (1 - sum(a))`` (NaN if ``sum(a) = 1``)."""
        den = 1.0 - math.fsum(self.a)
        return self.c / den if den != 0.0 else math.nan

    def first_order(self) -> FirstOrderModel:
        """The first-order summary: DC gain and dominant time constant, or why not.

        Returns
        -------
        FirstOrderModel
            Valid when every pole is inside the unit circle and the dominant one
            is real and in (0, 1).

        Examples
        --------
        >>> ArxModel(a=(1.2, -0.35), b=(0.1, 0.05), dt=2.0).first_order()  # doctest: +NUMBER
        FirstOrderModel(K=1.0, tau=5.607347, reason=None, theta=0.0)
        """
        lag = self._first_order_lag()
        return lag.with_dead_time(self.delay * self.dt) if lag.valid else lag

    def _first_order_lag(self) -> FirstOrderModel:
        if len(self.a) == 1 and len(self.b) == 1:
            return FirstOrderModel.from_discrete(self.a[0], self.b[0], self.dt)
        coeffs = [*self.a, *self.b]
        if not all(math.isfinite(x) for x in coeffs):
            return FirstOrderModel(math.nan, math.nan, INVALID_REASONS[NON_FINITE])
        poles = self.poles
        p = poles[0]
        if abs(p) >= 1.0:
            return FirstOrderModel(
                math.nan,
                math.nan,
                f"pole {_fmt_complex(p)} has |p| = {abs(p):.6g} >= 1: the model is unstable "
                "or integrating and has no time constant",
            )
        if len(poles) > 1 and abs(poles[1]) == abs(p) and poles[1] != p:
            return FirstOrderModel(
                math.nan,
                math.nan,
                f"dominant pole is complex ({_fmt_complex(p)}): the model oscillates and has no "
                "first-order time constant",
            )
        if p.imag != 0.0:
            return FirstOrderModel(
                math.nan,
                math.nan,
                f"dominant pole is complex ({_fmt_complex(p)}): the model oscillates and has no "
                "first-order time constant",
            )
        if p.real <= 0.0:
            return FirstOrderModel(
                math.nan,
                math.nan,
                f"dominant pole {p.real:.6g} <= 0: the model alternates sign each sample and has "
                "no time constant",
            )
        gain = math.fsum(self.b) / (1.0 - math.fsum(self.a))
        return FirstOrderModel(gain, -self.dt / math.log(p.real))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description: coefficients, order, ``K``, ``tau``, ``ambient``."""
        fo = self.first_order()
        return {
            "a": [float(x) for x in self.a],
            "b": [float(x) for x in self.b],
            "c": float(self.c),
            "delay": self.delay,
            "dt": self.dt,
            "K": finite_or_none(fo.K),
            "tau": finite_or_none(fo.tau),
            "theta": finite_or_none(fo.theta),
            "valid": fo.valid,
            "reason": fo.reason,
            "ambient": finite_or_none(self.ambient),
        }


def _fmt_complex(p: complex) -> str:
    return f"{p.real:.6g}{p.imag:+.6g}j" if p.imag != 0.0 else f"{p.real:.6g}"
