"""Identification of a first-order (or ARX) model from sampled input/output data.

The paper's four methods, each a function returning a result object:

* :func:`least_squares` — batch least squares (LSM, eq. 12) → :class:`LeastSquaresResult`;
* :func:`block_least_squares` — an estimate per block of samples (LSM(2), LSM(3)) →
  :class:`Trajectory`;
* :func:`moving_window_least_squares` — a FIFO window, an estimate per sample (MALSM) →
  :class:`Trajectory`;
* :func:`weighted_least_squares` — recursive least squares with a forgetting
  factor, in the paper's form and the standard one (WLSM) → :class:`Trajectory`;
* the step response method lives in :mod:`thermolab.ident.step`;
* :func:`output_error` — the output-error fit of a first order plus dead time
  (the unbiased alternative to the ARX methods) → :class:`OutputErrorResult`.

What makes a result trustworthy: the operating point decided from the data
(:mod:`~thermolab.ident.operating_point`, ``offset="auto"``), the dead time
(:mod:`~thermolab.ident.deadtime`), and validation like MATLAB's ``compare``
and ``resid`` with plausibility and timing checks
(:mod:`~thermolab.ident.diagnostics`). Every result lists its ``warnings``.

Sample-by-sample forms of every method, for a running experiment, are in
:mod:`thermolab.ident.online`; every method and setting is declared once in
:mod:`thermolab.ident.registry`. Models and the ``W <-> (K, tau)`` conversion are in
:mod:`thermolab.ident.models`, the general ARX model in :mod:`thermolab.ident.arx`.

The names below are imported on first use (PEP 562), so that the command
line can read the light :mod:`~thermolab.ident.registry` without loading NumPy
and SciPy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._warning import IdentificationWarning
    from .arx import ArxModel
    from .batch import least_squares
    from .blocks import block_least_squares
    from .deadtime import DelaySearch
    from .diagnostics import ResidualTest
    from .lsm_result import LeastSquaresResult
    from .models import (
        FIRST_ORDER,
        INVALID_REASONS,
        ArxOrder,
        FirstOrderModel,
        discrete_to_first_order,
    )
    from .oe import output_error
    from .oe_result import OutputErrorResult
    from .online import Estimate, OnlineIdentifier, make_identifier
    from .operating_point import OperatingPoint, decide_operating_point
    from .recursive import moving_window_least_squares, weighted_least_squares
    from .step import step_response
    from .step_result import StepResponseResult
    from .trajectory import Trajectory

__all__ = [
    "FIRST_ORDER",
    "INVALID_REASONS",
    "ArxModel",
    "ArxOrder",
    "DelaySearch",
    "Estimate",
    "FirstOrderModel",
    "IdentificationWarning",
    "LeastSquaresResult",
    "OnlineIdentifier",
    "OperatingPoint",
    "OutputErrorResult",
    "ResidualTest",
    "StepResponseResult",
    "Trajectory",
    "block_least_squares",
    "decide_operating_point",
    "discrete_to_first_order",
    "least_squares",
    "make_identifier",
    "moving_window_least_squares",
    "output_error",
    "step_response",
    "weighted_least_squares",
]

# Where each public name lives; read by __getattr__ on first access. No module
# may share a public name (importing ``.x`` sets the package's attribute ``x``
# to the module, and __getattr__ is then never asked): output_error lives in oe.
_HOME = {
    "FIRST_ORDER": "models",
    "INVALID_REASONS": "models",
    "ArxModel": "arx",
    "ArxOrder": "models",
    "FirstOrderModel": "models",
    "discrete_to_first_order": "models",
    "LeastSquaresResult": "lsm_result",
    "block_least_squares": "blocks",
    "least_squares": "batch",
    "Estimate": "online",
    "OnlineIdentifier": "online",
    "make_identifier": "online",
    "moving_window_least_squares": "recursive",
    "weighted_least_squares": "recursive",
    "IdentificationWarning": "_warning",
    "StepResponseResult": "step_result",
    "step_response": "step",
    "Trajectory": "trajectory",
    "DelaySearch": "deadtime",
    "ResidualTest": "diagnostics",
    "OperatingPoint": "operating_point",
    "decide_operating_point": "operating_point",
    "OutputErrorResult": "oe_result",
    "output_error": "oe",
}


def __getattr__(name: str) -> Any:
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{home}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
