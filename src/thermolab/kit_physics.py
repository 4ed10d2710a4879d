"""The TCLab kit's two-heater energy balance, as numerics: states, exact steps, sensor readings.

The kit has two heaters (transistors) each glued to a temperature sensor
(a TMP36) on one board. Each heater loses heat to the room and exchanges
heat with the other; each sensor lags behind its heater. With ``TH1``,
``TH2`` the heaters' and ``TS1``, ``TS2`` the sensors' temperatures, ``Ta``
the room's, and heater power ``P_i Q_i`` (the PWM limit ``P_i`` in counts
of 255, the heater ``Q_i`` in %)::

    dTH1/dt = k P1 Q1 + (Ta - TH1) / tau_a - (TH1 - TH2) / tau_x
    dTH2/dt = k f2 P2 Q2 + (Ta - TH2) / tau_a + (TH1 - TH2) / tau_x
    dTS1/dt = (TH1 - TS1) / tau_s
    dTS2/dt = (TH2 - TS2) / tau_s

A sensor reading adds Gaussian noise and is quantised the way the kit's
10-bit converter quantises a TMP36 (3.3 V / 1024 counts at 10 mV/°C: about
0.32 °C a count), within the sensor's range.

(``f2`` is 1 in the published model.) It is APMonitor's energy balance of the
kit without its radiation terms: ``tau_a = m cp / (U A)``, ``tau_x = m cp /
(Us As)``, ``k P_i = alpha_i / (m cp)``.

The model is linear with piecewise constant inputs, so :class:`KitPhysics`
steps it exactly (a matrix exponential per step length, cached) instead of
integrating it: any step length gives the same trajectory.
:func:`simulate_kit` runs it over arrays of heater inputs, by default with
:data:`KIT_FIT`, the constants fitted to real kits' records.

This module imports nothing of the lab, its rigs or its clients: both the
offline :class:`thermolab.tclab.TCLabModel` and a twin can use it.

References
----------
1. J. C. Kantor, "Modeling and Control of the Temperature Control
   Laboratory", CBE 30338 course notes, University of Notre Dame
   (github.com/jckantor/CBE30338, chapters 2–4): the four-state structure
   of two heater–sensor pairs.
2. The ``tclab`` package 1.0.0 (github.com/jckantor/TCLab), whose
   ``TCLabModel`` publishes the per-unit constants used here as defaults:
   ``k`` = 1/5720 K/(s·%·count), ``tau_a`` = 20 s, ``tau_x`` = 100 s,
   ``tau_s`` = 140 s, ambient 21 °C, P1 = 200, P2 = 100, noise 0.043 °C,
   a quantum of 0.3223 °C and a range of −50 to 132.2 °C.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ["KIT_FIT", "KitConstants", "KitPhysics", "sensor_reading", "simulate_kit"]


@dataclass(frozen=True, slots=True)
class KitConstants:
    """The kit's constants (defaults: the published ones, see :mod:`thermolab.kit_physics`).

    Attributes
    ----------
    ambient : float
        Room temperature, °C.
    heater_gain : float
        Heating rate per unit of heater power, K/s per (% × PWM count).
    tau_ambient : float
        Time constant of a heater's loss to the room, s.
    tau_exchange : float
        Time constant of the heat exchange between the two heaters, s.
    tau_sensor : float
        Time constant of a sensor behind its heater, s.
    noise : float
        Standard deviation of a reading's noise, °C (before quantisation).
    quantum : float
        One count of the sensor's converter, °C.
    low, high : float
        The sensor's range, °C.
    p1, p2 : float
        The heaters' PWM limits at power-up, counts of 255.
    heater2_factor : float
        Heater 2's heating per unit of power relative to heater 1's (1 in the
        published model, where heater 2 is weaker only by its lower PWM limit;
        a real kit's two heaters differ more, see :data:`KIT_FIT`).
    """

    ambient: float = 21.0
    heater_gain: float = 1.0 / 5720.0
    tau_ambient: float = 20.0
    tau_exchange: float = 100.0
    tau_sensor: float = 140.0
    noise: float = 0.043
    quantum: float = 0.3223
    low: float = -50.0
    high: float = 132.2
    p1: float = 200.0
    p2: float = 100.0
    heater2_factor: float = 1.0

    def __post_init__(self) -> None:
        for name in ("tau_ambient", "tau_exchange", "tau_sensor", "quantum", "heater2_factor"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"KitConstants.{name} must be positive; got {value!r}")
        if not self.noise >= 0:
            raise ValueError(f"KitConstants.noise must be at least 0 °C; got {self.noise!r}")


def sensor_reading(
    temperature: float, constants: KitConstants, rng: random.Random | None = None
) -> float:
    """What the kit reads for a sensor at ``temperature`` °C: noise, then the converter's count.

    The converter truncates to its count below (the kit reports the count's
    lower edge) and saturates at the sensor's range.

    Examples
    --------
    >>> c = KitConstants(noise=0.0)
    >>> sensor_reading(21.0, c)
    20.9495
    >>> sensor_reading(500.0, c), sensor_reading(-80.0, c)
    (132.2, -50.0)
    """
    noisy = temperature
    if constants.noise > 0:
        noisy += (rng or random).gauss(0.0, constants.noise)
    counted = math.floor(noisy / constants.quantum) * constants.quantum
    return round(min(max(counted, constants.low), constants.high), 4)


# States relative to the ambient: d/dt dev = A dev + B (heating rates of H1, H2, K/s).
_INPUT_MATRIX = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])


def _state_matrix(c: KitConstants) -> npt.NDArray[np.float64]:
    a, x, s = 1.0 / c.tau_ambient, 1.0 / c.tau_exchange, 1.0 / c.tau_sensor
    return np.array(
        [[-a - x, x, 0.0, 0.0], [x, -a - x, 0.0, 0.0], [s, 0.0, -s, 0.0], [0.0, s, 0.0, -s]]
    )


@dataclass
class KitPhysics:
    """The kit's four temperatures, stepped exactly under constant heater inputs.

    Parameters
    ----------
    constants : KitConstants
    temperatures : tuple of 4 floats, optional
        ``(TH1, TH2, TS1, TS2)`` in °C at the start (default: all at the ambient).

    Examples
    --------
    >>> kit = KitPhysics()
    >>> kit.advance(600.0, q1=50.0, q2=0.0, p1=200.0, p2=100.0)
    >>> th1, th2, ts1, ts2 = kit.temperatures
    >>> round(ts1, 1), round(ts2, 1)  # sensor 2 warms through the heaters' exchange
    (50.5, 25.9)
    """

    constants: KitConstants = field(default_factory=KitConstants)
    temperatures: tuple[float, float, float, float] | None = None
    _steps: dict[float, tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]] = field(
        default_factory=dict, init=False, repr=False
    )

    def __post_init__(self) -> None:
        if self.temperatures is None:
            self.temperatures = (self.constants.ambient,) * 4
        if len(self.temperatures) != 4:
            raise ValueError(
                f"KitPhysics needs 4 temperatures (TH1, TH2, TS1, TS2); got {self.temperatures!r}"
            )
        self._A = _state_matrix(self.constants)
        self._B = _INPUT_MATRIX

    def _step(self, dt: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        key = round(dt, 9)
        cached = self._steps.get(key)
        if cached is None:
            # The exponential of [[A, B], [0, 0]] holds both the state's and the input's map.
            block = np.zeros((6, 6))
            block[:4, :4], block[:4, 4:] = self._A * key, self._B * key
            from scipy.linalg import expm  # at first use: a lab's start imports no SciPy

            whole = expm(block)
            cached = (whole[:4, :4], whole[:4, 4:])
            if len(self._steps) > 64:  # irregular steps (a notebook's own timing) vary a lot
                self._steps.clear()
            self._steps[key] = cached
        return cached

    def advance(self, dt: float, *, q1: float, q2: float, p1: float, p2: float) -> None:
        """Let ``dt`` seconds pass with heaters ``q1``, ``q2`` (%) under PWM limits ``p1``, ``p2``.

        Raises
        ------
        ValueError
            For a negative or non-finite ``dt``.
        """
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"the kit's time step must be at least 0 s; got {dt!r}")
        if dt == 0:
            return
        assert self.temperatures is not None
        c = self.constants
        state_map, input_map = self._step(dt)
        deviation = np.array(self.temperatures) - c.ambient
        heating = np.array([c.heater_gain * p1 * q1, c.heater_gain * c.heater2_factor * p2 * q2])
        after = state_map @ deviation + input_map @ heating + c.ambient
        self.temperatures = (float(after[0]), float(after[1]), float(after[2]), float(after[3]))


def simulate_kit(
    t: npt.ArrayLike,
    q1: npt.ArrayLike,
    q2: npt.ArrayLike,
    constants: KitConstants | None = None,
    *,
    ambient: float | tuple[float, float] | None = None,
    readings: bool = False,
    seed: int | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The kit's two sensors at the times ``t`` for heaters ``q1``, ``q2`` held from each time.

    The kit is at rest at the ambient at ``t[0]``; ``q1[i]``, ``q2[i]`` (%)
    act from ``t[i]`` until ``t[i + 1]`` (a record's row: the temperatures
    read, then the heaters written), under the power-up PWM limits
    ``constants.p1``, ``constants.p2``. Exact steps (one matrix exponential
    per distinct step length), so any sampling gives the same trajectory.

    Parameters
    ----------
    t : array_like
        Increasing times, s (irregular sampling is fine).
    q1, q2 : array_like
        Heaters, % (clipped to 0–100 as the kit does).
    constants : KitConstants, optional
        Default: :data:`KIT_FIT`, the constants fitted to real kits.
    ambient : float or (float, float), optional
        The room, °C, or one figure per sensor (a real kit's two sensors read
        the same room up to a few tenths apart: a record's own first readings).
        Default: ``constants.ambient``.
    readings : bool
        ``False``: the sensors' temperatures. ``True``: what the kit reports,
        :func:`sensor_reading` of each (noise, then the converter's count).
    seed : int, optional
        Seeds the readings' noise.

    Returns
    -------
    T1, T2 : ndarray
        Sensor 1 and 2 at ``t``, °C.

    Examples
    --------
    Heater 1 at 50 % for ten minutes, heater 2 off, on the kit the published
    constants describe and on the one fitted to real records:

    >>> t = np.arange(0.0, 601.0)
    >>> q1, q2 = np.full(t.size, 50.0), np.zeros(t.size)
    >>> T1, T2 = simulate_kit(t, q1, q2, KitConstants())
    >>> round(float(T1[-1]), 1), round(float(T2[-1]), 1)
    (50.5, 25.9)
    >>> T1, T2 = simulate_kit(t, q1, q2)  # the default: the kit fitted to real records
    >>> round(float(T1[-1]), 1), round(float(T2[-1]), 1)
    (55.0, 33.4)

    What the kit would report, on the converter's counts:

    >>> T1, T2 = simulate_kit(t, q1, q2, readings=True, seed=1)
    >>> counts = T1 / KIT_FIT.quantum
    >>> bool(np.allclose(counts, np.round(counts), atol=1e-3))
    True
    """
    c = constants if constants is not None else KIT_FIT
    times = np.asarray(t, dtype=np.float64)
    heat1 = np.clip(np.asarray(q1, dtype=np.float64), 0.0, 100.0)
    heat2 = np.clip(np.asarray(q2, dtype=np.float64), 0.0, 100.0)
    if times.ndim != 1 or heat1.shape != times.shape or heat2.shape != times.shape:
        raise ValueError("t, q1 and q2 must be 1-D arrays of one length")
    steps = np.diff(times)
    if not (np.all(np.isfinite(times)) and np.all(steps >= 0)):
        raise ValueError("the times must be finite and never decrease")
    room = c.ambient if ambient is None else ambient
    room1, room2 = (room, room) if isinstance(room, int | float) else room
    # One exponential of [[A, B], [0, 0]] per distinct step length (a record's
    # jitter makes hundreds; scipy's expm takes them as one stack).
    lengths, which = np.unique(np.round(steps, 9), return_inverse=True)
    blocks = np.zeros((lengths.size, 6, 6))
    blocks[:, :4, :4] = _state_matrix(c)[None] * lengths[:, None, None]
    blocks[:, :4, 4:] = _INPUT_MATRIX[None] * lengths[:, None, None]
    from scipy.linalg import expm  # at first use: a lab's start imports no SciPy

    whole = expm(blocks) if lengths.size else blocks
    gain = c.heater_gain
    heating = np.stack([gain * c.p1 * heat1, gain * c.heater2_factor * c.p2 * heat2], axis=1)
    deviation = np.zeros((times.size, 4))
    for i, k in enumerate(which):
        step = whole[k]
        deviation[i + 1] = step[:4, :4] @ deviation[i] + step[:4, 4:] @ heating[i]
    T1, T2 = deviation[:, 2] + room1, deviation[:, 3] + room2
    if readings:
        rng = random.Random(seed)
        T1 = np.array([sensor_reading(v, c, rng) for v in T1])
        T2 = np.array([sensor_reading(v, c, rng) for v in T2])
    return T1, T2


KIT_FIT = KitConstants(
    heater_gain=2.012e-5,
    heater2_factor=0.3274,
    tau_ambient=257.1,
    tau_exchange=372.9,
    tau_sensor=13.18,
)
"""The kit's constants fitted to real TCLab records: the two-heater twin's default.

Fitted on 2026-11-29 by ``python benchmarks/bench_kit_twin_fit.py --refit``
(``scipy.optimize.least_squares`` on the simulated minus the measured T1 and
T2 of each record, every record weighted alike, from the published constants
and from their mirror image, the lower cost kept; each sensor's ambient is its
record's first readings). Fitted: ``heater_gain``, ``heater2_factor``,
``tau_ambient``, ``tau_exchange``, ``tau_sensor``; the PWM limits (200, 100),
the noise (0.043 °C) and the converter's count (0.3223 °C: a 10-bit converter
on 3.3 V reading a TMP36's 10 mV/°C, the step of the kit's records of the
original firmware) are the published ones.

Fitting records: Kantor's ``Step_Test_Data.csv`` and ``StepTestData.csv``
(jckantor/CBE30338), ``step_test_data.csv`` (jckantor/TCLab), ``TCLab_data.csv``
(APMonitor/pds), and two two-heater records of APMonitor/arduino
(``Energy_balance_MIMO/.../data.txt``, ``2nd_order_MIMO/GEKKO/data.txt``).
Held out: ``fromShared/step01.csv`` (jckantor/CBE30338, one heater) and
``Hybrid_MIMO/Python_GEKKO/data.txt`` (APMonitor/arduino, two heaters).
The records come from different kits, which differ by more than the model's
error on any one of them: one set of constants follows a kit it was not fitted
to within several °C (``docs/kit-twin.md`` has the table, beside the
published constants'). The slow loss to the room with a fast sensor is the
mirror image of the published fast loss with a slow sensor; a single heater's
step cannot tell them apart.
"""
