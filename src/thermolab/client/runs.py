"""A run fetched from the lab as NumPy arrays (:class:`RunData`), pandas on request."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["RunData"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class RunData:
    """A run's record: every channel as a float64 array, with the run and its results.

    Attributes
    ----------
    run : dict
        The run as ``GET /api/runs/{run}`` describes it (status, dt, results...).
    columns : dict of str to ndarray
        Every channel by name, ``t``, ``u``, ``y`` first (missing values NaN).
    units : dict of str to str
        Each channel's unit.
    methods : dict
        Each method's result as the lab stored it.
    """

    run: dict[str, Any]
    columns: dict[str, FloatArray]
    units: dict[str, str] = field(default_factory=dict)
    methods: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_export(cls, body: dict[str, Any]) -> RunData:
        """Build from the lab's ``GET /api/runs/{run}/export.json`` body."""
        channels = body.get("channels") or []
        samples = body.get("samples") or {}
        columns = {
            spec["name"]: np.array(
                [np.nan if v is None else v for v in samples.get(spec["name"], [])],
                dtype=np.float64,
            )
            for spec in channels
        }
        units = {spec["name"]: str(spec.get("unit") or "") for spec in channels}
        return cls(dict(body.get("run") or {}), columns, units, dict(body.get("methods") or {}))

    @property
    def t(self) -> FloatArray:
        """Sample times, s."""
        return self.columns["t"]

    @property
    def u(self) -> FloatArray:
        """The input."""
        return self.columns["u"]

    @property
    def y(self) -> FloatArray:
        """The output."""
        return self.columns["y"]

    def __getitem__(self, name: str) -> FloatArray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(
                f"run {self.run.get('id')} has no channel {name!r}; "
                f"it has {', '.join(self.columns)}"
            ) from None

    def __len__(self) -> int:
        return len(self.columns["t"]) if "t" in self.columns else 0

    def to_pandas(self) -> pandas.DataFrame:
        """The record as a pandas ``DataFrame`` (one column per channel, indexed by sample).

        Raises
        ------
        ImportError
            Without pandas, saying how to install it (it is optional).
        """
        try:
            import pandas
        except ImportError:
            raise ImportError(
                "RunData.to_pandas needs pandas, which is optional: pip install pandas "
                "(the arrays are in RunData.columns without it)"
            ) from None
        frame = pandas.DataFrame(self.columns)
        frame.attrs["units"] = dict(self.units)
        frame.attrs["run"] = self.run.get("id")
        return frame
