"""Reproduction of the paper's Table I (simulation results).

Every row of Table I is defined here as data (:data:`TABLE1_ROWS`): its input
signal, record length, method and settings, and the figures the paper printed.
:func:`reproduce_table1` runs every row with :mod:`thermolab.ident` on the exact
simulation of the reference model (:data:`thermolab.simulation.REFERENCE_MODEL`)
and returns ours beside the paper's, with the deviation.

The same machinery runs the *variants* that test explanations of the rows the
exact simulation does not reproduce (``docs/reproduction.md`` gives the
experiments and their figures):

* ``solver="explicit-inverse"``: eq. 12 computed verbatim, ``W = (DᵀD)⁻¹DᵀY``
  with an explicit inverse, in double precision (LSM and MALSM rows);
* ``covariance="frozen"``: WLSM with ``P`` held at ``pmax·I`` instead of being
  propagated by eq. 15 (WLSM rows);
* ``noise``, ``quantum``, ``decimals`` and ``precision="float32"``: the
  measured output disturbed by Gaussian noise, quantised (a 16-bit ±10 V DAQ
  has ``quantum = 20/65536`` V), rounded as a spreadsheet file would store it,
  or stored in single precision (every row).

Conventions (decided where the paper is silent, see ``docs/reproduction.md``):

* a record is sampled at ``t = 0, 1, ... s`` with ``y[k]`` read before ``u[k]``
  is applied (:mod:`thermolab.simulation`); the step rows step from 0 to 10 V at
  ``t = 1 s`` (START, then the set point changes), 2000 samples;
* the paper's simulated records start at 0 V, so the methods run with
  ``offset="none"``, the paper's raw regression;
* a WLSM run lasts until 2000 samples after convergence (the paper's
  "duration of 2000 seconds after convergence"): convergence is found on a
  longer pilot record (at least twice the run), the run is cut
  ``after_convergence`` samples after the later of the two convergence samples,
  and the statistics are taken over those last samples.

The package's modules: the paper's table as data (``_table``: :data:`TABLE1_ROWS`;
``_figures``: :class:`Stats`, :class:`Convergence`, :class:`Figures`), the
options (``_options``: :class:`Table1Options`), running the rows (``_running``:
:func:`reproduce_table1`; ``_variants``: the variants' arithmetic) and the
results with their formatting and plots (``_results``: :class:`RowResult`,
:class:`Table1Result`). Import from :mod:`thermolab.reproduction`.
"""

from __future__ import annotations

from ._figures import Convergence, Figures, Stats
from ._options import COVARIANCES as COVARIANCES  # the options' choices, as before the split
from ._options import DAQ_16BIT_QUANTUM, Table1Options
from ._options import PRECISIONS as PRECISIONS
from ._options import SOLVERS as SOLVERS
from ._options import Covariance as Covariance
from ._options import Precision as Precision
from ._options import Solver as Solver
from ._results import RowResult, Table1Result
from ._running import reproduce_table1
from ._table import TABLE1_ROWS, Table1Row
from ._table import Method as Method  # a type; tests/ident/test_registry.py reads it

__all__ = [
    "DAQ_16BIT_QUANTUM",
    "TABLE1_ROWS",
    "Convergence",
    "Figures",
    "RowResult",
    "Stats",
    "Table1Options",
    "Table1Result",
    "Table1Row",
    "reproduce_table1",
]
