"""How well a run kept its sampling times: computed once at the end, stored with the run.

A real rig is read when the operating system wakes the sampling loop: each
sample is read ``lateness`` seconds after its scheduled instant, and the
periods between the readings (``t_read``) spread. Methods that assume a fixed
``dt`` are biased when that spread is large, so the figures and a warning go
with the run (API and page).

A twin is different: it advances by exactly ``dt`` per sample whatever the
wall clock does (the runner hands it each sample's scheduled instant), so its
data are exact and wall-clock lateness says nothing about them: for a twin no
lateness is reported. The spread is measured on the reading's own time
(``t_read``, the instant the state was actually taken) for both kinds: for a
twin that is exactly the scheduled instant unless its preset simulates
jitter, and then it warns like a real rig.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.jsonsafe import finite_or_none

__all__ = ["JITTER_LIMIT", "timing_summary"]

#: Spread of the sample period (standard deviation over the median) beyond which
#: methods that assume a fixed period are biased enough to warn (5 %, the library's limit).
JITTER_LIMIT = 0.05


def timing_summary(
    t_read: npt.ArrayLike,
    lateness: npt.ArrayLike,
    dt: float,
    *,
    simulated: bool,
) -> dict[str, Any]:
    """The run's timing figures and, when they would bias the methods, a warning.

    Parameters
    ----------
    t_read, lateness : array_like
        The runner's per-sample reading time and wall-clock lateness (s).
    dt : float
        The run's sample period (s).
    simulated : bool
        Whether the rig is a twin (its data are timed by ``t``, not the wall clock).

    Returns
    -------
    dict
        ``rig`` (``"real"`` or ``"twin"``), ``maxLateness`` and
        ``p95Lateness`` (s; ``None`` for a twin: not part of its data),
        ``periodSpread`` (std of the periods over their median), ``warnings``
        (list of str).

    Examples
    --------
    >>> t = np.arange(5.0)
    >>> timing_summary(t + [0, 0.3, 0, 0.3, 0], [0, 0.3, 0, 0.3, 0], 1.0, simulated=False)[
    ...     "warnings"][0][:40]
    'timing jitter: the sample period spreads'
    >>> timing_summary(t, t * 0 + 0.3, 1.0, simulated=True)["maxLateness"] is None
    True
    """
    times = np.asarray(t_read, dtype=float)
    late = np.asarray(lateness, dtype=float)
    spread = 0.0
    if times.size >= 3:
        periods = np.diff(times)
        median = float(np.median(periods))
        if median > 0:
            spread = float(np.std(periods) / median)
    warnings: list[str] = []
    if spread > JITTER_LIMIT:
        warnings.append(
            f"timing jitter: the sample period spreads {100 * spread:.1f} % around dt = {dt:g} s "
            f"(over {100 * JITTER_LIMIT:.0f} %), which biases the methods that assume a fixed "
            "period; run fewer programs on the lab's computer or choose a longer dt"
        )
    real = not simulated and late.size > 0
    return {
        "rig": "twin" if simulated else "real",
        "maxLateness": finite_or_none(float(late.max())) if real else None,
        "p95Lateness": finite_or_none(float(np.percentile(late, 95))) if real else None,
        "periodSpread": finite_or_none(spread),
        "warnings": warnings,
    }
