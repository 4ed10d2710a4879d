"""The ``tclab`` package's ``Plotter``: a live chart of a historian (matplotlib, lazily)."""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from typing import Any

from thermolab.tclab.historian import Historian

__all__ = ["Plotter"]


class Plotter:
    """Plot the last ``twindow`` seconds of a historian's columns; :meth:`update` adds a row.

    Redrawing costs far more than a row: as in the ``tclab`` package the
    chart is redrawn at most :attr:`fps` times a real second (and at least
    every :attr:`maxskip` lab seconds), so a fast loop keeps its pace.

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
        except ImportError:  # pragma: no cover - matplotlib is a test dependency
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
        self._drawn_at = -float("inf")  # real time of the last redraw
        self._drawn_t = -float("inf")  # lab time it showed

    fps = 3.0
    """Redraws per real second, at most."""
    maxskip = 50.0
    """Lab seconds the chart may lag behind the log."""

    def update(self, tnow: float | None = None) -> None:
        """Log a row in the historian and redraw."""
        self.historian.update(tnow)
        data = self.historian.logdict
        t = data["Time"]
        now = time.monotonic()
        if now - self._drawn_at < 1.0 / self.fps and t[-1] - self._drawn_t < self.maxskip:
            return
        self._drawn_at, self._drawn_t = now, t[-1]
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
            # Through import_module: IPython is optional, and untyped where it is installed.
            shown = importlib.import_module("IPython.display")
            kernel = importlib.import_module("IPython").get_ipython()
        except ImportError:
            return
        if kernel is None:  # IPython installed, but no notebook or shell to show it in
            return
        if self._display is None:
            self._display = shown.display(self.figure, display_id=True)
        else:
            self._display.update(self.figure)
