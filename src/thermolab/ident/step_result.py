"""What the step response method (:func:`thermolab.ident.step.step_response`) returns."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from ._step_fit import LEVEL_63
from .models import FirstOrderModel

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["StepResponseResult"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class StepResponseResult:
    """What the step response method found.

    Attributes
    ----------
    K : float
        Gain from the settled change of the output (``final_value_basis`` says how
        it was obtained): ``(final_value - baseline) / amplitude``.
    tau : float
        Time constant in seconds: the time from the step to the 63.2 % (``1 - 1/e``)
        crossing of the settled change, interpolated between samples.
    K_last_sample : float
        The paper's gain: ``(y[-1] - baseline) / amplitude``, the last sample taken as
        the final value.
    tau_fit : float
        Time constant of the exponential fitted to the tail (NaN if there was no fit).
    final_value_basis : str
        ``"extrapolated"`` (from the tail fit) or ``"last sample"`` (no usable fit).
    tau_basis : str
        ``"63.2% crossing"`` or ``"tail fit"`` (the record ends before the crossing).
    step_index : int
        First sample recorded with the new input.
    step_time : float
        Time of that sample (seconds); ``tau`` is counted from it.
    u_before, u_after : float
        Input levels before and after the step (volts).
    amplitude : float
        ``u_after - u_before``; negative for a cooling step.
    baseline : float
        Output before the step: the mean of the samples up to the step sample.
    final_value : float
        Settled output, ``baseline + K amplitude``.
    last_value : float
        The last output sample.
    t63 : float
        Time of the 63.2 % crossing (NaN when ``tau_basis`` is ``"tail fit"``).
    direction : {"heating", "cooling"}
        The sign of the step.
    settled : bool
        True when the record lasts at least ``settle_time_constants`` time constants
        after the step.
    time_constants_recorded : float
        Record length after the step, in time constants.
    n_samples : int
        Samples in the record.
    dt : float
        Median sample period (seconds).
    warnings : tuple of str
        Everything that makes the figures less trustworthy (also emitted as
        :class:`~thermolab.ident.IdentificationWarning`).
    theta : float
        Dead time in seconds: first order plus dead time fitted through the
        28.3 % and 63.2 % crossings (``t28 = theta + tau/3``, ``t63 = theta +
        tau``); ``tau`` is then ``t63 - theta``. 0 when the two agree with no delay,
        or when the delay found is within what the noise could make (two standard
        deviations of the two-point estimate).
    theta_first_response : float
        Time from the step to the last sample before the output first leaves the
        noise band (four noise deviations) for good: the dead time as seen
        directly, to a sample (NaN when not found).

    Notes
    -----
    The record arrays are kept for :meth:`plot` but are not part of the result's
    value (equality and ``repr`` ignore them).
    """

    K: float
    tau: float
    K_last_sample: float
    tau_fit: float
    final_value_basis: str
    tau_basis: str
    step_index: int
    step_time: float
    u_before: float
    u_after: float
    amplitude: float
    baseline: float
    final_value: float
    last_value: float
    t63: float
    direction: Literal["heating", "cooling"]
    settled: bool
    time_constants_recorded: float
    n_samples: int
    dt: float
    warnings: tuple[str, ...] = ()
    theta: float = 0.0
    theta_first_response: float = math.nan
    t: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)
    u: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)
    y: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)

    @property
    def trusted(self) -> bool:
        """Finite ``K`` and a positive ``tau`` with no warning: figures to show as final."""
        return (
            math.isfinite(self.K)
            and math.isfinite(self.tau)
            and self.tau > 0.0
            and not self.warnings
        )

    @property
    def model(self) -> FirstOrderModel:
        """The identified model ``K exp(-theta s) / (tau s + 1)`` (settled gain)."""
        return FirstOrderModel(self.K, self.tau, theta=self.theta)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """A JSON-safe summary (NaN and inf become ``None``).

        Parameters
        ----------
        arrays : bool, optional
            Also include the record, ``t``, ``u`` and ``y``. Default False.

        Returns
        -------
        dict
            ``method`` (``"srm"``), every scalar attribute, ``warnings`` (a list) and
            ``trusted``.

        Examples
        --------
        >>> import numpy as np
        >>> from thermolab.ident import step_response
        >>> from thermolab.simulation import simulate_first_order
        >>> t = np.arange(3000.0)
        >>> u = np.where(t >= 1, 10.0, 0.0)
        >>> d = step_response(t, u, simulate_first_order(u, 0.14, 250.0, 1.0)).to_dict()
        >>> d["method"], round(d["K"], 6), round(d["tau"], 6), d["warnings"]
        ('srm', 0.14, 250.0, [])
        """
        out: dict[str, Any] = {"method": "srm"}
        for name in (
            "K",
            "tau",
            "K_last_sample",
            "tau_fit",
            "final_value_basis",
            "tau_basis",
            "step_index",
            "step_time",
            "u_before",
            "u_after",
            "amplitude",
            "baseline",
            "final_value",
            "last_value",
            "t63",
            "direction",
            "settled",
            "time_constants_recorded",
            "n_samples",
            "dt",
            "theta",
            "theta_first_response",
        ):
            value = getattr(self, name)
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[name] = value
        out["warnings"] = list(self.warnings)
        out["trusted"] = self.trusted
        if arrays:
            for name in ("t", "u", "y"):
                out[name] = [float(v) for v in getattr(self, name)]
        return out

    def plot(self, *, title: str | None = None) -> Figure:
        """The record, the identified response and the 63.2 % point (the paper's Fig. 5).

        Parameters
        ----------
        title : str, optional
            Figure title; default gives ``K``, ``tau`` and the step.

        Returns
        -------
        matplotlib.figure.Figure
            Output (top) and input (bottom) against time; not attached to pyplot
            (save it with ``fig.savefig(path)``).

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        """
        from ._plotting import _figure

        fig = _figure()
        ax_y, ax_u = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
        ax_y.plot(self.t, self.y, color="k", linewidth=1, label="measured")
        after = self.t >= self.step_time + self.theta
        change = self.final_value - self.baseline
        elapsed = self.t[after] - self.step_time - self.theta
        model = self.baseline + change * -np.expm1(-elapsed / self.tau)
        ax_y.plot(self.t[after], model, color="tab:red", linewidth=1, label="first-order model")
        ax_y.axhline(self.baseline, color="0.5", linewidth=0.8, linestyle=":")
        ax_y.axhline(
            self.final_value,
            color="tab:red",
            linewidth=0.8,
            linestyle="--",
            label=f"final value ({self.final_value_basis})",
        )
        if math.isfinite(self.t63):
            ax_y.plot(
                [self.t63],
                [self.baseline + LEVEL_63 * change],
                "o",
                color="tab:blue",
                label="63.2 % of the change",
            )
        ax_u.step(self.t, self.u, where="post", color="tab:blue", linewidth=1)
        ax_y.set_ylabel("y (V)")
        ax_u.set_ylabel("u (V)")
        ax_u.set_xlabel("time (s)")
        for ax in (ax_y, ax_u):
            ax.grid(True, alpha=0.3)
        ax_y.legend(loc="best")
        fig.suptitle(
            title
            or f"step response ({self.direction}, {self.u_before:.4g} → {self.u_after:.4g} V): "
            f"K = {self.K:.6g}, tau = {self.tau:.6g} s"
        )
        return fig
