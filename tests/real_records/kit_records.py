"""Real TCLab records as the two-heater twin sees them, and the fit of the kit's constants.

Each :class:`KitSpec` reads one record as two heaters (% held from each row's
time) and two sensors (°C); a record of one heater has ``Q2`` = 0, and one
sensor's record has no ``T2``. The kit is at rest before its first heater
change; each sensor's ambient is its own mean over the rows before it (at most
the first ten; the first row where a heater is on from the start).

:func:`fit` fits ``heater_gain``, ``heater2_factor``, ``tau_ambient``,
``tau_exchange`` and ``tau_sensor`` of :class:`thermolab.kit_physics.KitConstants`
(the published PWM limits 200 and 100 kept) to the fitting records by
``scipy.optimize.least_squares`` on the simulated minus the measured sensors,
each record weighted alike. :func:`scores` gives the RMS error per record and
per step of each heater.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from thermolab.kit_physics import KitConstants, simulate_kit

Array = npt.NDArray[np.float64]

HERE = Path(__file__).resolve().parent
SHARED = HERE.parents[1].parent / "shared" / "real-records"
"""``../shared/real-records`` beside the repository root (its ``SOURCE.md``)."""
COPIED = HERE / "kit"
"""Records copied into the repository (``kit/SOURCE.md``: source, commit, licence)."""


@dataclass(frozen=True)
class KitSpec:
    """How to read one record for the two-heater twin.

    Attributes
    ----------
    name : str
        The record's short name.
    path : Path
        Its file.
    columns : tuple
        0-based positions of time, Q1, Q2, T1, T2 (``None``: Q2 off all
        along, or T2 not recorded).
    header : bool
        Whether the first non-``#`` line names the columns.
    held_out : bool
        Not used by the fit.
    """

    name: str
    path: Path
    columns: tuple[int, int, int | None, int, int | None]
    header: bool = True
    held_out: bool = False


SPECS: tuple[KitSpec, ...] = (
    KitSpec("kantor_Step_Test_Data", SHARED / "kantor_Step_Test_Data.csv", (0, 3, None, 1, 2)),
    KitSpec("kantor_StepTestData", SHARED / "kantor_StepTestData.csv", (0, 3, None, 1, 2)),
    KitSpec("tclab_step_test_data", SHARED / "tclab_step_test_data.csv", (1, 2, None, 3, 4)),
    KitSpec("apm_pds_TCLab_data", SHARED / "apm_pds_TCLab_data.csv", (0, 1, None, 2, None)),
    KitSpec("apm_arduino_mimo_data", SHARED / "apm_arduino_mimo_data.txt", (0, 1, 2, 3, 4)),
    KitSpec("apm_2nd_order_mimo_data", COPIED / "apm_2nd_order_mimo_data.txt", (0, 1, 2, 3, 4)),
    # Held out, chosen before the first fit: the corpus's held-out one-heater
    # record, and a two-heater record of another day's random steps.
    KitSpec("kantor_step01", SHARED / "kantor_step01.csv", (0, 3, 4, 1, 2), held_out=True),
    KitSpec(
        "apm_hybrid_mimo_data", COPIED / "apm_hybrid_mimo_data.txt", (0, 1, 2, 3, 4),
        held_out=True,
    ),
)  # fmt: skip


@dataclass(frozen=True)
class KitRecord:
    """A record read by its spec: times (s), heaters (%), sensors (°C; T2 NaN if absent)."""

    spec: KitSpec
    t: Array
    q1: Array
    q2: Array
    T1: Array
    T2: Array

    @property
    def heaters(self) -> int:
        """1 when heater 2 stays off, else 2."""
        return 2 if np.any(self.q2 != self.q2[0]) else 1

    @property
    def ambient(self) -> tuple[float, float]:
        """Each sensor's mean over the rest before the first heater change (≤ 10 rows).

        A record without ``T2`` gives sensor 2 the room of sensor 1.
        """
        on = np.flatnonzero((self.q1 != 0) | (self.q2 != 0))
        rest = max(1, min(10, int(on[0]) if on.size else self.t.size))
        room1 = float(np.mean(self.T1[:rest]))
        room2 = float(np.mean(self.T2[:rest]))
        return room1, room2 if math.isfinite(room2) else room1


@functools.cache
def load(spec: KitSpec) -> KitRecord:
    """Read a record (NumPy only). Equal time stamps: the earlier moves back a median step."""
    wanted = [c for c in spec.columns if c is not None]
    data = np.loadtxt(
        spec.path, delimiter=",", comments="#", skiprows=1 if spec.header else 0,
        usecols=wanted, ndmin=2,
    )  # fmt: skip
    column = {c: np.ascontiguousarray(data[:, j]) for j, c in enumerate(wanted)}
    t_col, q1_col, q2_col, t1_col, t2_col = spec.columns
    t = column[t_col].copy()
    dt = float(np.median(np.diff(t)))
    for i in np.flatnonzero(np.diff(t) <= 0)[::-1]:
        t[i] = t[i + 1] - dt
    nothing = np.full(t.shape, np.nan)
    q2 = column[q2_col] if q2_col is not None else np.zeros(t.shape)
    T2 = column[t2_col] if t2_col is not None else nothing
    return KitRecord(spec, t - t[0], column[q1_col], q2, column[t1_col], T2)


def records(held_out: bool | None = None) -> list[KitRecord]:
    """The records (``held_out``: only those held out, or only the fitting ones)."""
    return [load(s) for s in SPECS if held_out is None or s.held_out == held_out]


def simulate(record: KitRecord, constants: KitConstants) -> tuple[Array, Array]:
    """The twin's sensors on a record's heaters, from each sensor's ambient."""
    return simulate_kit(record.t, record.q1, record.q2, constants, ambient=record.ambient)


FITTED = ("heater_gain", "heater2_factor", "tau_ambient", "tau_exchange", "tau_sensor")


def _constants(x: Array, base: KitConstants, names: tuple[str, ...] = FITTED) -> KitConstants:
    return replace(base, **{n: float(math.exp(v)) for n, v in zip(names, x, strict=True)})


def _residuals(recs: list[KitRecord], constants: KitConstants) -> Array:
    parts = []
    for r in recs:
        T1, T2 = simulate(r, constants)
        error = np.r_[T1 - r.T1, T2 - r.T2]
        error = error[np.isfinite(error)]
        parts.append(error / math.sqrt(error.size))  # each record weighs alike
    return np.concatenate(parts)


STARTS = (
    KitConstants(),
    KitConstants(heater_gain=3e-5, tau_ambient=150.0, tau_exchange=300.0, tau_sensor=30.0),
)
"""The fit's starts: the published constants, and their mirror image. A sensor behind
its heater is two lags in series, so a slow heater with a fast sensor fits one
heater's step as well as the published fast heater with a slow sensor (single
records fit either way); the other sensor tells them apart, weakly."""


def cost(recs: list[KitRecord], constants: KitConstants) -> float:
    """The fit's objective: the sum over records of the mean squared error (°C²)."""
    return float(np.sum(_residuals(recs, constants) ** 2))


def fit(recs: list[KitRecord] | None = None) -> KitConstants:
    """The constants of :data:`FITTED` that fit ``recs`` best (default: the fitting records).

    From each of :data:`STARTS`, the lowest :func:`cost` wins; the other
    constants (noise, quantum, PWM limits) stay the published ones, and so
    does ``heater2_factor`` where heater 2 never moves (nothing decides it).
    Each constant stays within three decades of its start.
    """
    recs = records(held_out=False) if recs is None else recs
    names = (
        FITTED
        if any(r.heaters == 2 for r in recs)
        else tuple(n for n in FITTED if n != "heater2_factor")
    )
    best: KitConstants | None = None
    for base in STARTS:
        x0 = np.log([getattr(base, n) for n in names])
        span = math.log(1e3)
        result = least_squares(
            lambda x, b=base: _residuals(recs, _constants(x, b, names)), x0,
            bounds=(x0 - span, x0 + span),
        )  # fmt: skip
        found = _constants(result.x, base, names)
        if best is None or cost(recs, found) < cost(recs, best):
            best = found
    assert best is not None
    return best


@dataclass(frozen=True)
class Score:
    """RMS errors (°C) of the twin on one record: each sensor, and each step of each heater."""

    record: str
    heaters: int
    held_out: bool
    T1: float
    T2: float
    steps: tuple[tuple[str, float, float], ...]
    """(heater, its step's time in s, RMS of its own sensor until the next change)."""

    def over_steps(self, heater: str) -> float:
        """RMS over every step of ``heater`` (``Q1``: T1, ``Q2``: T2), NaN without one."""
        values = [rms for h, _, rms in self.steps if h == heater]
        return float(np.sqrt(np.mean(np.square(values)))) if values else math.nan


def _rms(error: Array) -> float:
    error = error[np.isfinite(error)]
    return float(np.sqrt(np.mean(error**2))) if error.size else math.nan


def score(record: KitRecord, constants: KitConstants) -> Score:
    """The twin's RMS errors on ``record``."""
    return score_on(record, simulate(record, constants))


def score_on(record: KitRecord, sensors: tuple[Array, Array]) -> Score:
    """The RMS errors on ``record`` of any simulation's sensors ``(T1, T2)`` at its times."""
    T1, T2 = sensors
    e1, e2 = T1 - record.T1, T2 - record.T2
    # A heater on from the first row stepped from rest (0 %) at the record's start.
    moved1, moved2 = np.diff(record.q1, prepend=0.0) != 0, np.diff(record.q2, prepend=0.0) != 0
    changes = np.flatnonzero(moved1 | moved2)
    ends = [*changes[1:].tolist(), record.t.size]
    steps = []
    for start, end in zip(changes.tolist(), ends, strict=True):
        for heater, moved, error in (("Q1", moved1, e1), ("Q2", moved2, e2)):
            if moved[start]:
                steps.append((heater, float(record.t[start]), _rms(error[start:end])))
    return Score(
        record.spec.name, record.heaters, record.spec.held_out, _rms(e1), _rms(e2), tuple(steps)
    )
