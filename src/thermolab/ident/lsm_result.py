"""The result of batch least squares (:func:`thermolab.ident.least_squares`) and its summary."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from thermolab.jsonsafe import finite_or_none

from . import diagnostics as _diag
from .arx import ArxModel
from .deadtime import DelaySearch
from .models import ArxOrder, FirstOrderModel
from .operating_point import OperatingPoint

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["LeastSquaresResult"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class LeastSquaresResult:
    """The batch least-squares estimate of a record and its diagnostics.

    Attributes
    ----------
    W : numpy.ndarray
        Estimated parameters, named by ``param_names`` (``[a, b]`` for first order,
        ``[..., c]`` with ``offset="fit"``).
    param_names : tuple of str
        Names of ``W``'s entries.
    order : ArxOrder
        Model structure.
    offset : str or float
        How the operating point was handled (see :func:`least_squares`).
    dt : float
        Sample period in seconds.
    model : FirstOrderModel
        ``K`` (DC gain) and ``tau`` (dominant time constant), or the reason the
        estimate has none (``model.reason``).
    arx : ArxModel
        The full discrete model (in the offset frame: deviations from ``y_shift``).
    stderr : numpy.ndarray
        Standard errors of ``W``: ``sqrt(diag(s² (DᵀD)⁻¹))`` with ``s²`` the
        residual variance over ``n_rows - n_params`` degrees of freedom (NaN when
        there are none). Exact for white equation error (the ARX noise model);
        with white *measurement* noise on ``y`` the estimates are biased and
        their actual spread is usually smaller than this.
    K_stderr, tau_stderr : float
        Standard errors of ``K`` and ``tau`` propagated from the covariance of
        ``W`` to first order (delta method); NaN when the model is not valid.
    cond : float
        2-norm condition number of the regressor matrix ``D``.
    cond_scaled : float
        Condition number of ``D`` with unit-norm columns: what limits accuracy
        (about ``cond_scaled * 1e-16`` relative error in ``W`` for exact data).
    k : numpy.ndarray of int
        Sample index of each target ``y[k]`` (``order.lag + 1 .. n-1``).
    y_measured, y_one_step, y_simulated : numpy.ndarray
        Measured targets, one-step predictions ``D W`` and the free-run
        simulation of the model from the record's first samples driven by ``u``,
        all in absolute volts, aligned with ``k``.
    residuals : numpy.ndarray
        ``y_measured - y_one_step``.
    fit_one_step, fit_simulation : float
        NRMSE fit in percent, ``100 (1 - ||y - ŷ|| / ||y - mean(y)||)``: 100 is
        perfect, 0 is no better than the mean; NaN when the output is constant,
        ``-inf`` when the simulation diverges.
    n_samples : int
        Samples in the record.
    ambient : float
        The operating point: ``c / (1 - sum(a))`` with ``offset="fit"``, otherwise
        the output value removed (0 for ``offset="none"``).
    y_shift : float
        The value subtracted from ``y`` before regressing (``y[0]`` for
        ``"initial"``, the given value for a float, else 0).
    operating_point : OperatingPoint or None
        How ``offset="auto"`` decided the handling (None when it was given).
    delay_search : DelaySearch or None
        The dead time search (None when the order was given).
    residual_test : ResidualTest or None
        Whiteness and input independence of the residuals (MATLAB's ``resid``).
    fit_holdout : float
        Fit % of the free-run simulation on the last ``holdout`` part of the
        record, by a model fitted to the rest (NaN when too short or when the
        input does not change in that part).
    warnings : tuple of str
        Everything that makes the model less trustworthy (also emitted as
        :class:`IdentificationWarning`), each with the likely cause.
    """

    W: FloatArray
    param_names: tuple[str, ...]
    order: ArxOrder
    offset: str | float
    dt: float
    model: FirstOrderModel
    arx: ArxModel
    stderr: FloatArray
    K_stderr: float
    tau_stderr: float
    cond: float
    cond_scaled: float
    k: npt.NDArray[np.intp]
    y_measured: FloatArray
    y_one_step: FloatArray
    y_simulated: FloatArray
    residuals: FloatArray
    fit_one_step: float
    fit_simulation: float
    n_samples: int
    ambient: float
    y_shift: float
    operating_point: OperatingPoint | None = None
    delay_search: DelaySearch | None = None
    residual_test: _diag.ResidualTest | None = None
    fit_holdout: float = math.nan
    warnings: tuple[str, ...] = ()

    @property
    def K(self) -> float:  # noqa: N802 - the paper's symbol
        """Static (DC) gain; NaN when the model has no first-order meaning."""
        return self.model.K

    @property
    def theta(self) -> float:
        """Dead time in seconds: ``order.delay * dt``."""
        return self.order.delay * self.dt

    @property
    def trusted(self) -> bool:
        """A valid first-order model with no warning: one to show as final."""
        return self.model.valid and not self.warnings

    @property
    def tau(self) -> float:
        """Time constant in seconds; NaN when the model has no first-order meaning."""
        return self.model.tau

    @property
    def n_rows(self) -> int:
        """Number of regression rows (targets)."""
        return int(self.k.size)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """A JSON-safe summary (NaN and inf become ``None``).

        Parameters
        ----------
        arrays : bool, optional
            Also include ``k``, ``y_measured``, ``y_one_step``, ``y_simulated`` and
            ``residuals``. Default False.

        Returns
        -------
        dict
            ``method`` (``"lsm"``), ``dt``, ``K``, ``tau``, ``valid``, ``reason``,
            ``W``, ``param_names``, ``stderr``, ``K_stderr``, ``tau_stderr``,
            ``cond``, ``cond_scaled``, ``fit_one_step``, ``fit_simulation``,
            ``n_samples``, ``n_rows``, ``order``, ``offset``, ``ambient``, and
            ``theta`` (dead time, s), ``fit_holdout``, ``operating_point``
            (:meth:`OperatingPoint.to_dict` or None), ``delay_search``
            (:meth:`DelaySearch.to_dict` or None), ``residual_test``
            (:meth:`ResidualTest.to_dict` or None), ``warnings`` (list of str) and
            ``trusted`` (valid and no warning).
        """
        out: dict[str, Any] = {
            "method": "lsm",
            "dt": self.dt,
            "K": finite_or_none(self.K),
            "tau": finite_or_none(self.tau),
            "valid": self.model.valid,
            "reason": self.model.reason,
            "W": [finite_or_none(x) for x in self.W],
            "param_names": list(self.param_names),
            "stderr": [finite_or_none(x) for x in self.stderr],
            "K_stderr": finite_or_none(self.K_stderr),
            "tau_stderr": finite_or_none(self.tau_stderr),
            "cond": finite_or_none(self.cond),
            "cond_scaled": finite_or_none(self.cond_scaled),
            "fit_one_step": finite_or_none(self.fit_one_step),
            "fit_simulation": finite_or_none(self.fit_simulation),
            "n_samples": self.n_samples,
            "n_rows": self.n_rows,
            "order": self.order.to_dict(),
            "offset": self.offset,
            "ambient": finite_or_none(self.ambient),
            "theta": self.theta,
            "fit_holdout": finite_or_none(self.fit_holdout),
            "operating_point": None
            if self.operating_point is None
            else self.operating_point.to_dict(),
            "delay_search": None if self.delay_search is None else self.delay_search.to_dict(),
            "residual_test": None if self.residual_test is None else self.residual_test.to_dict(),
            "warnings": list(self.warnings),
            "trusted": self.trusted,
        }
        if arrays:
            for name in ("y_measured", "y_one_step", "y_simulated", "residuals"):
                arr: FloatArray = getattr(self, name)
                out[name] = [finite_or_none(x) for x in arr.tolist()]
            out["k"] = self.k.tolist()
        return out

    def plot(self, *, title: str | None = None) -> Figure:
        """Measured output beside the one-step prediction and the free-run simulation.

        Parameters
        ----------
        title : str, optional
            Figure title; default gives ``K``, ``tau`` and the two fits.

        Returns
        -------
        matplotlib.figure.Figure
            A figure not attached to pyplot (save it with ``fig.savefig(path)``).

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        """
        from ._plotting import plot_least_squares

        return plot_least_squares(self, title=title)
