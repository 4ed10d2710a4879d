"""JSON-safe values: the one place that turns NaN and infinities into ``None``.

JSON has neither NaN nor infinity, and NumPy scalars and arrays are not JSON
types. Every ``to_dict()``, API answer, live message and CLI report goes
through :func:`json_safe` (or :func:`finite_or_none` for one float), so the
rule is written once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["finite_or_none", "json_safe"]


def finite_or_none(x: float) -> float | None:
    """``float(x)`` if it is finite, else ``None``.

    Examples
    --------
    >>> finite_or_none(1.5), finite_or_none(float("nan")), finite_or_none(np.float64("inf"))
    (1.5, None, None)
    """
    x = float(x)
    return x if math.isfinite(x) else None


def json_safe(value: Any) -> Any:
    """``value`` with NaN/inf replaced by ``None`` and NumPy types made plain.

    Mappings become dicts with string keys; tuples, lists and arrays become
    lists; NumPy scalars become Python scalars. Anything else is returned as it
    is.

    Examples
    --------
    >>> json_safe({"K": float("nan"), "W": (1.0, float("inf")), "k": np.int64(3)})
    {'K': None, 'W': [1.0, None], 'k': 3}
    >>> json_safe(np.array([0.5, np.nan]))
    [0.5, None]
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, str | int | bool) or value is None:
        return value
    if isinstance(value, np.generic):
        return json_safe(value.item())
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value
