"""What the output-error fit (:func:`thermolab.ident.oe.output_error`) returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.jsonsafe import finite_or_none

from . import diagnostics as _diag
from .models import ArxOrder, FirstOrderModel

__all__ = ["OutputErrorResult"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class OutputErrorResult:
    """The output-error FOPDT fit of a record.

    Attributes
    ----------
    model : FirstOrderModel
        ``K``, ``tau`` and ``theta`` (dead time, seconds).
    ambient : float
        Output at rest with the input off (volts).
    x0 : float
        The record's initial deviation from ambient (``K u0`` for a settled start).
    stderr : dict of str to float
        Standard errors of ``K``, ``tau``, ``theta``, ``ambient``, ``x0`` from the
        Jacobian at the solution (white measurement noise).
    fit_simulation : float
        NRMSE fit % of the simulation on the record.
    residual_test : ResidualTest or None
        Whiteness and input independence of the simulation errors.
    start : ArxOrder
        The dead time the ARX starting point found (its ``delay``).
    n_samples : int
    dt : float
    nfev : int
        Simulations the optimiser ran.
    warnings : tuple of str
    y_simulated, residuals : numpy.ndarray
        The simulated output (absolute volts) and ``y - y_simulated``.
    """

    model: FirstOrderModel
    ambient: float
    x0: float
    stderr: dict[str, float]
    fit_simulation: float
    residual_test: _diag.ResidualTest | None
    start: ArxOrder
    n_samples: int
    dt: float
    nfev: int
    warnings: tuple[str, ...] = ()
    y_simulated: FloatArray = field(default_factory=lambda: np.empty(0), repr=False)
    residuals: FloatArray = field(default_factory=lambda: np.empty(0), repr=False)

    @property
    def K(self) -> float:  # noqa: N802 - the paper's symbol
        """Static gain."""
        return self.model.K

    @property
    def tau(self) -> float:
        """Time constant in seconds."""
        return self.model.tau

    @property
    def theta(self) -> float:
        """Dead time in seconds."""
        return self.model.theta

    @property
    def trusted(self) -> bool:
        """A valid model with no warning."""
        return self.model.valid and not self.warnings

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-safe summary.

        Returns
        -------
        dict
            ``method`` (``"oe"``), ``dt``, ``K``, ``tau``, ``theta``, ``valid``,
            ``reason``, ``ambient``, ``x0``, ``stderr`` (dict), ``fit_simulation``,
            ``residual_test``, ``n_samples``, ``nfev``, ``warnings``, ``trusted``
            and, with ``arrays``, ``y_simulated`` and ``residuals``.
        """
        out: dict[str, Any] = {
            "method": "oe",
            "dt": self.dt,
            "K": finite_or_none(self.K),
            "tau": finite_or_none(self.tau),
            "theta": finite_or_none(self.theta),
            "valid": self.model.valid,
            "reason": self.model.reason,
            "ambient": finite_or_none(self.ambient),
            "x0": finite_or_none(self.x0),
            "stderr": {k: finite_or_none(v) for k, v in self.stderr.items()},
            "fit_simulation": finite_or_none(self.fit_simulation),
            "residual_test": None if self.residual_test is None else self.residual_test.to_dict(),
            "n_samples": self.n_samples,
            "nfev": self.nfev,
            "warnings": list(self.warnings),
            "trusted": self.trusted,
        }
        if arrays:
            out["y_simulated"] = [finite_or_none(x) for x in self.y_simulated.tolist()]
            out["residuals"] = [finite_or_none(x) for x in self.residuals.tolist()]
        return out
