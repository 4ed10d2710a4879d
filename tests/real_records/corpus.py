"""The real-record corpus: how to read each record, and FOPDT fits that are not ThermoLab's.

The records live outside the repository, in ``../shared/real-records/`` beside
the repository root (``SOURCE.md`` there gives each one's repository, path,
commit and licence). Each :class:`Spec` says how to read one record as the
user has it: the columns (0-based positions), their units, which heater, and
what the record's notebook assumes before its first row.

Two reference fits of a first order plus dead time,

    y(t) = y0 + K * sum_j du_j * (1 - exp(-(t - t_j - theta) / tau)),  t > t_j + theta,

(the input held from each time stamp to the next, exactly as recorded), both
on the record's own time stamps and neither using :mod:`thermolab.ident`:

* ``scipy``: the formula above, exact at every time stamp, least squares on
  ``K, tau, theta, y0`` by ``scipy.optimize.least_squares`` from several
  starting dead times;
* ``control``: python-control's ``forced_response`` of ``K / (tau s + 1)``
  on a 0.1 s grid, the input delayed by ``theta`` on that grid, read at the
  record's time stamps, fitted by Nelder-Mead from a generic start (the
  peer; skipped where python-control is missing).

A method's model is *right* when it is within :data:`K_TOL` and
:data:`TAU_TOL` (relative) and :data:`THETA_TOL` (seconds) of either fit
(:func:`references`); the peer's fit counts only when it fits the record about
as well as SciPy's (RMS error at most :data:`PEER_RMSE` times), since the dead
time's minimum is shallow and a worse local optimum is no reference.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares, minimize

Array = npt.NDArray[np.float64]

K_TOL = 0.10
TAU_TOL = 0.10
THETA_TOL = 5.0
PEER_RMSE = 1.10

ROOT = Path(__file__).resolve().parents[2]
FOLDER = ROOT.parent / "shared" / "real-records"
"""``../shared/real-records`` from the repository root (a worktree's root alike)."""


@dataclass(frozen=True)
class Spec:
    """How to read one real record.

    Attributes
    ----------
    name : str
        A short name (the file name, ``:T2`` for the second heater).
    file : str
        The file in :data:`FOLDER`.
    columns : tuple of int
        The 0-based positions of time, heater and temperature.
    header : bool
        Whether the first non-``#`` line names the columns.
    u_unit, y_unit : str
        The units as recorded (``%``, ``PWM`` counts; ``°C``, ``°F``, ``K``).
    heater : str
        Which heater drives the record (``Q1``, ``Q2``).
    rest_before : bool
        The heater is on from the first row; the record's notebook assumes
        the kit at rest, heater off, before it: a row ``(t0 - 1 s, 0, y0)``
        is put first.
    held_out : bool
        No rule was tuned on this record.
    shape : str
        The test: ``single step``, ``multi-step``.
    """

    name: str
    file: str
    columns: tuple[int, int, int]
    header: bool = True
    u_unit: str = "%"
    y_unit: str = "°C"
    heater: str = "Q1"
    rest_before: bool = False
    held_out: bool = False
    shape: str = "single step"

    @property
    def path(self) -> Path:
        """The record's file."""
        return FOLDER / self.file


SPECS: tuple[Spec, ...] = (
    Spec("kantor_Step_Test_Data", "kantor_Step_Test_Data.csv", (0, 3, 1)),
    Spec("kantor_StepTestData", "kantor_StepTestData.csv", (0, 3, 1)),
    Spec("tclab_step_test_data", "tclab_step_test_data.csv", (1, 2, 3), rest_before=True),
    Spec("apm_pds_TCLab_data", "apm_pds_TCLab_data.csv", (0, 1, 2), shape="multi-step"),
    Spec(
        "apm_arduino_data", "apm_arduino_data.csv", (0, 1, 2), u_unit="PWM", y_unit="°F",
        shape="multi-step",
    ),
    Spec("che436_step_test", "che436_step_test.csv", (0, 1, 6), shape="multi-step"),
    Spec(
        "apm_arduino_mimo_data:T1", "apm_arduino_mimo_data.txt", (0, 1, 3), shape="multi-step",
    ),
    # Held out: chosen before any rule was changed (one irregular single step, one
    # headerless kelvin multi-step, the second heater), and never looked at while tuning.
    Spec("kantor_step01", "kantor_step01.csv", (0, 3, 1), rest_before=True, held_out=True),
    Spec(
        "apm_arduino_data_step_test", "apm_arduino_data_step_test.csv", (0, 1, 2),
        header=False, u_unit="PWM", y_unit="K", held_out=True, shape="multi-step",
    ),
    Spec(
        "apm_arduino_mimo_data:T2", "apm_arduino_mimo_data.txt", (0, 2, 4), heater="Q2",
        held_out=True, shape="multi-step",
    ),
)  # fmt: skip


@dataclass(frozen=True)
class Data:
    """A record read by its spec: times (s), heater, temperature, as recorded."""

    spec: Spec
    t: Array
    u: Array
    y: Array


def load(spec: Spec) -> Data:
    """Read a record by its spec (NumPy only: the reader under test is not used here).

    Rows with a time stamp equal to the next one are the rest before a step
    (``kantor_Step_Test_Data``: two rows at t = 0): the earlier is moved back
    by the median spacing, so the times increase.
    """
    data = np.loadtxt(
        spec.path, delimiter=",", comments="#", skiprows=1 if spec.header else 0,
        usecols=spec.columns, ndmin=2,
    )  # fmt: skip
    t, u, y = (np.ascontiguousarray(data[:, j]) for j in range(3))
    dt = float(np.median(np.diff(t)))
    for i in np.flatnonzero(np.diff(t) <= 0)[::-1]:
        t[i] = t[i + 1] - dt
    if spec.rest_before:
        t, u, y = np.r_[t[0] - dt, t], np.r_[0.0, u], np.r_[y[0], y]
    return Data(spec, t, u, y)


def write_tuy(data: Data, path: Path) -> Path:
    """Write ``t,u,y`` with full precision (what ``thermolab identify`` reads by default)."""
    columns = zip(data.t.tolist(), data.u.tolist(), data.y.tolist(), strict=True)
    rows = "\n".join(f"{a!r},{b!r},{c!r}" for a, b, c in columns)
    path.write_text("t,u,y\n" + rows + "\n")
    return path


# --- the reference fits -------------------------------------------------------------------


def fopdt_response(t: Array, u: Array, K: float, tau: float, theta: float, y0: float) -> Array:
    """The FOPDT output at the time stamps ``t`` for the input held as recorded.

    The kit is at rest with the first input before the record starts; each
    change of ``u`` at ``t[i]`` reaches the output ``theta`` later.
    """
    changes = np.flatnonzero(np.diff(u) != 0) + 1
    out = np.full(t.shape, y0, dtype=np.float64)
    for i in changes:
        lag = t - t[i] - theta
        out += np.where(lag > 0, K * (u[i] - u[i - 1]) * -np.expm1(-np.maximum(lag, 0) / tau), 0)
    return out


@dataclass(frozen=True)
class Fit:
    """A reference FOPDT model: gain (output unit per input unit), tau and theta in s."""

    K: float
    tau: float
    theta: float
    y0: float
    rmse: float
    source: str

    def right(self, K: float | None, tau: float | None, theta: float | None) -> bool:
        """Whether ``K, tau, theta`` are within the tolerances of this fit."""
        if K is None or tau is None or not (math.isfinite(K) and math.isfinite(tau)):
            return False
        return (
            abs(K / self.K - 1) <= K_TOL
            and abs(tau / self.tau - 1) <= TAU_TOL
            and abs((theta or 0.0) - self.theta) <= THETA_TOL
        )


def _start(data: Data) -> tuple[float, float]:
    """A generic start: the gain of the largest swing, tau a fifth of the record."""
    du = float(np.ptp(data.u)) or 1.0
    return float(np.ptp(data.y)) / du, max(20.0, float(data.t[-1] - data.t[0]) / 5)


@functools.cache
def scipy_fit(spec: Spec) -> Fit:
    """The exact-at-the-time-stamps FOPDT least-squares fit (``scipy.optimize.least_squares``)."""
    d = load(spec)
    K0, tau0 = _start(d)

    def residual(p: Array) -> Array:
        return fopdt_response(d.t, d.u, p[0], p[1], p[2], p[3]) - d.y

    best = None
    for theta0 in (0.0, 5.0, 10.0, 20.0, 40.0):
        r = least_squares(
            residual, [K0, tau0, theta0, d.y[0]], bounds=([-np.inf, 1.0, 0.0, -np.inf],
            [np.inf, 1e4, 120.0, np.inf]), x_scale=[abs(K0) or 1.0, tau0, 10.0, 1.0],
        )  # fmt: skip
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    K, tau, theta, y0 = (float(v) for v in best.x)
    rmse = float(np.sqrt(np.mean(best.fun**2)))
    return Fit(K, tau, theta, y0, rmse, "scipy")


@functools.cache
def control_fit(spec: Spec, grid: float = 0.5) -> Fit:
    """The peer fit: python-control's ``forced_response`` on a fine grid, Nelder-Mead.

    Started from the SciPy fit's gain and time constant but from two dead times
    of its own (2 s and 15 s): a different simulator and optimiser that may
    settle in another of the dead time's shallow minima.
    """
    import control

    d = load(spec)
    fine = np.arange(d.t[0], d.t[-1] + grid, grid)
    held = np.searchsorted(d.t, fine, side="right") - 1  # the input as recorded, held

    def simulate(p: Array) -> Array:
        K, tau, theta, y0 = p
        shift = round(max(float(theta), 0.0) / grid)
        u = d.u[held] - d.u[0]
        u = np.r_[np.zeros(shift), u[: u.size - shift]] if shift else u
        sys = control.tf([K], [max(tau, 1e-3), 1.0])
        y = control.forced_response(sys, T=fine, U=u).outputs
        out: Array = np.interp(d.t, fine, np.asarray(y, dtype=np.float64)) + y0
        return out

    def cost(p: Array) -> float:
        return float(np.mean((simulate(p) - d.y) ** 2))

    start = scipy_fit(spec)
    best = None
    for theta0 in (2.0, 15.0):
        r = minimize(
            cost, [start.K, start.tau, theta0, start.y0], method="Nelder-Mead",
            options={"xatol": 1e-3, "fatol": 1e-8, "maxiter": 400, "adaptive": True},
        )  # fmt: skip
        if best is None or r.fun < best.fun:
            best = r
    assert best is not None
    K, tau, theta, y0 = (float(v) for v in best.x)
    return Fit(K, tau, theta, y0, math.sqrt(float(best.fun)), "control")


def references(spec: Spec, peer: bool = True) -> tuple[Fit, ...]:
    """The reference fits of a record: SciPy's, and the peer's where it is as good."""
    ref = scipy_fit(spec)
    if not peer:
        return (ref,)
    try:
        other = control_fit(spec)
    except ImportError:
        return (ref,)
    return (ref, other) if other.rmse <= PEER_RMSE * ref.rmse else (ref,)
