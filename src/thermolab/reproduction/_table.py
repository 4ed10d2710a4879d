"""The paper's Table I as data: every row's input, method, settings and printed figures.

:data:`TABLE1_ROWS` (re-exported by :mod:`thermolab.reproduction`) is read by
the runner (:mod:`thermolab.reproduction._running`), the command line and the
browser's Table I page.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

from thermolab.ident.registry import PAPER_W0, get_method

from ._figures import Convergence, Figures, Stats

__all__ = ["PILOT_START", "RUNS", "TABLE1_ROWS", "Method", "Table1Row"]

# thermolab.ident.registry.METHOD_NAMES as a type (tests/ident/test_registry.py keeps them equal).
Method = Literal["srm", "lsm", "blockls", "malsm", "wlsm", "oe"]

# A WLSM row's first pilot record (doubled until twice the run fits, see _running).
PILOT_START = 4096


def _paper(
    K: tuple[float, float, float],
    tau: tuple[float, float, float],
    converged: tuple[int, int] | None = None,
) -> Figures:
    return Figures(
        Stats(*K),
        Stats(*tau),
        None if converged is None else Convergence(*converged),
    )


@dataclass(frozen=True)
class Table1Row:
    """The definition of one row of Table I.

    Parameters
    ----------
    run : str
        The paper's name of the run (``"LSM(2)"``).
    method : {"srm", "lsm", "blockls", "malsm", "wlsm"}
        The identification method (:mod:`thermolab.ident`).
    signal : str
        The input, in the syntax of :func:`thermolab.signals.parse_signal`.
    samples : int
        Record length; for WLSM the length of the first pilot record (the run
        itself lasts until ``after_convergence`` samples after convergence).
    paper : Figures
        The figures printed in Table I.
    description : str
        The paper's description of the run.
    block, window : int or None, optional
        Block size (``blockls``) or window (``malsm``) in samples.
    gamma, pmax : float or None, optional
        WLSM forgetting factor and diagonal of the initial ``P`` (paper's form).
    w0 : tuple of float, optional
        WLSM initial parameters; the paper's ``[0.96329, 9.9082e-4]``.

    Examples
    --------
    >>> row = TABLE1_ROWS[5]
    >>> row.run, row.method, row.signal, row.gamma, row.pmax
    ('WLSM(1)', 'wlsm', 'square:0:4:0.1', 0.96, 10000.0)
    """

    run: str
    method: Method
    signal: str
    samples: int
    paper: Figures
    description: str
    block: int | None = None
    window: int | None = None
    gamma: float | None = None
    pmax: float | None = None
    w0: tuple[float, float] = PAPER_W0

    @property
    def slug(self) -> str:
        """A file-name-safe name: ``"LSM(2)"`` -> ``"lsm2"``."""
        return re.sub(r"[^a-z0-9]+", "", self.run.lower())

    def to_dict(self) -> dict[str, Any]:
        """The definition as JSON-safe data (without the paper's figures).

        Returns
        -------
        dict
            ``run``, ``method``, ``signal``, ``samples``, ``description`` and the
            settings that apply (``block``, ``window``, ``gamma``, ``pmax``, ``w0``).
        """
        out: dict[str, Any] = {
            "run": self.run,
            "method": self.method,
            "signal": self.signal,
            "samples": self.samples,
            "description": self.description,
        }
        for name in get_method(self.method).setting_names():
            value = getattr(self, name, None)
            if value is not None:
                out[name] = list(value) if isinstance(value, tuple) else value
        return out


_STEP = "step:0:10@1"
_SQUARE_46 = "square:4:6:0.1"
_SQUARE_04 = "square:0:4:0.1"

#: Every row of the paper's Table I, in the paper's order, with its printed figures.
TABLE1_ROWS: tuple[Table1Row, ...] = (
    Table1Row(
        "SRM",
        "srm",
        _STEP,
        2000,
        _paper((0.140042,) * 3, (250.126233,) * 3),
        "step 0->10 V, 2000 s; gain from the last sample, Ts at 63.2 %",
    ),
    Table1Row(
        "LSM(1)",
        "lsm",
        _STEP,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "step 0->10 V, 2000 s; one estimate from all 2000 samples",
    ),
    Table1Row(
        "LSM(2)",
        "blockls",
        _STEP,
        2000,
        _paper((0.140090, 0.140090, 0.140089), (250.125871, 250.126237, 250.120736)),
        "step 0->10 V, 2000 s; an estimate every 100 samples",
        block=100,
    ),
    Table1Row(
        "LSM(3)",
        "blockls",
        _SQUARE_46,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "square 4<->6 V at 0.1 Hz, 2000 s; an estimate every 100 samples",
        block=100,
    ),
    Table1Row(
        "MALSM",
        "malsm",
        _SQUARE_46,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "square 4<->6 V at 0.1 Hz, 2000 s; moving window of 100 samples",
        window=100,
    ),
    Table1Row(
        "WLSM(1)",
        "wlsm",
        _SQUARE_04,
        PILOT_START,
        _paper((0.140088, 0.140136, 0.139612), (250.126231, 250.126233, 250.125680), (54, 73)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e4",
        gamma=0.96,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(2)",
        "wlsm",
        _SQUARE_04,
        PILOT_START,
        _paper((0.140090, 0.140100, 0.139886), (250.126233, 250.126233, 250.126054), (29, 37)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.7, pmax 1e4",
        gamma=0.7,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(3)",
        "wlsm",
        _SQUARE_04,
        PILOT_START,
        _paper((0.140086, 0.140101, 0.139015), (250.117447, 250.126233, 247.576412), (108, 109)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e3",
        gamma=0.96,
        pmax=1e3,
    ),
    Table1Row(
        "WLSM(4)",
        "wlsm",
        _SQUARE_46,
        PILOT_START,
        _paper(
            (0.140300, 0.141490, 0.139242),
            (248.661922, 249.362239, 247.636940),
            (9816, 11724),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e4",
        gamma=0.96,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(5)",
        "wlsm",
        _SQUARE_46,
        PILOT_START,
        _paper(
            (0.140255, 0.141506, 0.139149),
            (248.343654, 248.912988, 247.625883),
            (14981, 18924),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.7, pmax 1e4",
        gamma=0.7,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(6)",
        "wlsm",
        _SQUARE_46,
        PILOT_START,
        _paper(
            (0.140333, 0.142151, 0.138689),
            (248.349385, 248.916889, 247.633954),
            (13849, 18933),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e3",
        gamma=0.96,
        pmax=1e3,
    ),
)

RUNS = {row.run: row for row in TABLE1_ROWS}
