"""Identified models as python-control objects, for a course that goes on in that library."""

from __future__ import annotations

from typing import Any

from thermolab.control.tuning import as_fopdt
from thermolab.errors import InvalidParameterError

__all__ = ["to_control"]


def to_control(model: Any, pade_order: int = 1) -> Any:
    """Return the model ``K e^{-θs} / (τs + 1)`` as a ``control.TransferFunction``.

    Parameters
    ----------
    model : FOPDT, tuple or object with K, tau (and theta)
        An identified model (see :func:`~thermolab.control.tuning.as_fopdt`).
    pade_order : int, optional
        Order of the Padé approximant of the dead time ``e^{-θs}`` (1..10,
        default 1); ignored when ``θ = 0``.

    Returns
    -------
    control.TransferFunction
        Continuous time, input and output in the rig's units.

    Raises
    ------
    InvalidParameterError
        If the model is not valid or ``pade_order`` is not in 1..10.
    ImportError
        If python-control is not installed (``pip install 'thermolab[control]'``).

    Examples
    --------
    >>> G = to_control((2.0, 10.0, 0.0))
    >>> [float(c) for c in G.num[0][0]], [float(c) for c in G.den[0][0]]
    ([2.0], [10.0, 1.0])
    >>> round(float(to_control((2.0, 10.0, 3.0), pade_order=2).dcgain()), 12)
    2.0
    """
    if isinstance(pade_order, bool) or not isinstance(pade_order, int) or not 1 <= pade_order <= 10:
        raise InvalidParameterError(f"pade_order must be an integer in 1..10, got {pade_order!r}")
    m = as_fopdt(model)
    try:
        import control
    except ImportError as exc:  # pragma: no cover - the test extra installs it
        raise ImportError(
            "to_control needs python-control: pip install 'thermolab[control]'"
        ) from exc
    plant = control.tf([m.K], [m.tau, 1.0])
    if m.theta > 0:
        num, den = control.pade(m.theta, pade_order)
        plant = plant * control.tf(num, den)
    return plant
