"""The TCLab kit's two-heater energy balance, as numerics: states, exact steps, sensor readings.

The kit has two heaters (transistors) each glued to a temperature sensor
(a TMP36) on one board. Each heater loses heat to the room and exchanges
heat with the other; each sensor lags behind its heater. With ``TH1``,
``TH2`` the heaters' and ``TS1``, ``TS2`` the sensors' temperatures, ``Ta``
the room's, and heater power ``P_i Q_i`` (the PWM limit ``P_i`` in counts
of 255, the heater ``Q_i`` in %)::

    dTH1/dt = k P1 Q1 + (Ta - TH1) / tau_a - (TH1 - TH2) / tau_x
    dTH2/dt = k P2 Q2 + (Ta - TH2) / tau_a + (TH1 - TH2) / tau_x
    dTS1/dt = (TH1 - TS1) / tau_s
    dTS2/dt = (TH2 - TS2) / tau_s

A sensor reading adds Gaussian noise and is quantised the way the kit's
10-bit converter quantises a TMP36 (3.3 V / 1024 counts at 10 mV/°C: about
0.32 °C a count), within the sensor's range.

The model is linear with piecewise constant inputs, so :class:`KitPhysics`
steps it exactly (a matrix exponential per step length, cached) instead of
integrating it: any step length gives the same trajectory.

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
from scipy.linalg import expm

__all__ = ["KitConstants", "KitPhysics", "sensor_reading"]


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

    def __post_init__(self) -> None:
        for name in ("tau_ambient", "tau_exchange", "tau_sensor", "quantum"):
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
        c = self.constants
        a, x, s = 1.0 / c.tau_ambient, 1.0 / c.tau_exchange, 1.0 / c.tau_sensor
        # States relative to the ambient: d/dt dev = A dev + B (heating rates of H1, H2).
        self._A = np.array(
            [[-a - x, x, 0.0, 0.0], [x, -a - x, 0.0, 0.0], [s, 0.0, -s, 0.0], [0.0, s, 0.0, -s]]
        )
        self._B = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])

    def _step(self, dt: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        key = round(dt, 9)
        cached = self._steps.get(key)
        if cached is None:
            # The exponential of [[A, B], [0, 0]] holds both the state's and the input's map.
            block = np.zeros((6, 6))
            block[:4, :4], block[:4, 4:] = self._A * key, self._B * key
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
        heating = np.array([c.heater_gain * p1 * q1, c.heater_gain * p2 * q2])
        after = state_map @ deviation + input_map @ heating + c.ambient
        self.temperatures = (float(after[0]), float(after[1]), float(after[2]), float(after[3]))
