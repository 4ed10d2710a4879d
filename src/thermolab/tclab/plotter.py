"""The ``tclab`` package's ``Plotter``: a live chart of a historian (matplotlib, lazily)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from thermolab.tclab.historian import Historian

__all__ = ["Plotter"]


class Plotter:
    """Plot the last ``twindow`` seconds of a historian's columns; :meth:`update` adds a row.

    Parameters
    ----------
    historian : Historian
    twindow : float
        Seconds shown.
    layout : sequence of sequences of str, optional
        Columns per chart (default: one chart per column).
    """

    def __init__(
        self,
        historian: Historian,
        twindow: float = 120.0,
        layout: Sequence[Sequence[str]] | None = None,
    ) -> None:
        try:
            import matplotlib.pyplot as plt
        except ImportError:
            raise ImportError(
                "Plotter needs matplotlib: pip install 'thermolab[plot]' (or matplotlib)"
            ) from None
        self.historian = historian
        self.twindow = float(twindow)
        self.layout = (
            [tuple(g) for g in layout] if layout else [(c,) for c in historian.columns[1:]]
        )
        self.figure, axes = plt.subplots(len(self.layout), 1, sharex=True, squeeze=False)
        self.axes = list(axes[:, 0])
        self.lines: dict[str, Any] = {}
        for ax, group in zip(self.axes, self.layout, strict=True):
            for name in group:
                (self.lines[name],) = ax.plot([], [], label=name)
            ax.legend(loc="upper left")
            ax.grid(True)
        self.axes[-1].set_xlabel("Time / s")
        self._display: Any = None

    def update(self, tnow: float | None = None) -> None:
        """Log a row in the historian and redraw."""
        self.historian.update(tnow)
        data = self.historian.logdict
        t = data["Time"]
        for name, line in self.lines.items():
            line.set_data(t, data[name])
        end = t[-1] if t else 0.0
        for ax in self.axes:
            ax.set_xlim(max(0.0, end - self.twindow), max(end, self.twindow))
            ax.relim()
            ax.autoscale_view(scalex=False)
        self.figure.canvas.draw_idle()
        self._show()

    def _show(self) -> None:
        try:
            from IPython.display import display  # type: ignore[import-not-found]
        except ImportError:
            return
        if self._display is None:
            self._display = display(self.figure, display_id=True)
        else:
            self._display.update(self.figure)
