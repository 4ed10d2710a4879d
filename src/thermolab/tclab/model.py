# ruff: noqa: N802  (T1, Q1, LED... are the kit's names, which notebooks call)
"""``TCLabModel``: the kit, offline — two heaters and two sensors simulated in lab time.

The ``tclab`` package's offline stand-in for the kit, name for name, so a
notebook switches with ``TCLab = setup(connected=False, speedup=10)`` (or by
naming ``TCLabModel``) and needs no lab. The physics is
:class:`thermolab.kit_physics.KitPhysics` (the published two-heater energy
balance, stepped exactly); time is :data:`~thermolab.tclab.labtime`, so a
speed-up runs it faster than real time.
"""

from __future__ import annotations

import random
import sys
from collections.abc import Callable
from typing import Any

from thermolab.kit_physics import KitConstants, KitPhysics, sensor_reading
from thermolab.tclab.labtime import labtime

__all__ = ["TCLabModel", "clip"]


def clip(val: float, lower: float = 0, upper: float = 100) -> float:
    """``val`` limited to ``[lower, upper]`` (a heater's 0–100 %, a PWM limit's 0–255).

    Raises
    ------
    ValueError
        For a value that is not a number (NaN included).
    """
    number = float(val)
    if number != number:
        raise ValueError(f"a heater value must be a number; got {val!r}")
    return float(max(lower, min(number, upper)))


class TCLabModel:
    """The TCLab kit simulated locally: ``T1``, ``T2``, ``Q1``, ``Q2``, ``P1``, ``P2``, ``LED``...

    Parameters
    ----------
    port : str
        Ignored (the kit's serial port), so that ``TCLab(...)`` calls run unchanged.
    debug : bool
        Print each command.
    synced : bool
        ``True``: the model follows :data:`~thermolab.tclab.labtime` on every
        call. ``False``: it moves only when :meth:`update` is given a time
        (as fast as the computer goes, as ``Experiment(synced=False)`` does).
    constants : KitConstants, optional
        The kit's constants (default: the published ones).
    seed : int, optional
        Seeds the sensors' noise (default: unseeded).

    Attributes
    ----------
    Ta : float
        Ambient temperature, °C.
    tstart : float
        Lab time at construction, s.
    sources : list of (name, callable or None)
        ``T1``, ``T2``, ``Q1``, ``Q2`` from one :meth:`scan`, for a
        :class:`~thermolab.tclab.Historian`.

    Examples
    --------
    >>> with TCLabModel(seed=1) as lab:  # doctest: +ELLIPSIS
    ...     lab.Q1(150), lab.Q2(-5)
    TCLabModel: the kit's two heaters and sensors, simulated offline...
    (100.0, 0.0)
    """

    def __init__(
        self,
        port: str = "",
        debug: bool = False,
        synced: bool = True,
        *,
        constants: KitConstants | None = None,
        seed: int | None = None,
    ) -> None:
        self.debug = debug
        self.synced = synced
        self.constants = constants or KitConstants()
        self._rng = random.Random(seed)
        self._kit = KitPhysics(self.constants)
        self.Ta = self.constants.ambient
        labtime.start()
        self.tstart = labtime.time()
        self.tlast = 0.0
        self.tnow = 0.0
        self._P1, self._P2 = self.constants.p1, self.constants.p2
        self._Q1 = self._Q2 = 0.0
        self._led = 0.0
        self.version = "TCLabModel (thermolab.kit_physics)"
        self.sources: list[tuple[str, Callable[[], Any] | None]] = [
            ("T1", self.scan),
            ("T2", None),
            ("Q1", None),
            ("Q2", None),
        ]
        pace = f"{labtime.get_rate():g}x" if labtime.get_rate() != 1 else "real time"
        print(f"TCLabModel: the kit's two heaters and sensors, simulated offline at {pace}.")

    def __enter__(self) -> TCLabModel:
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> None:
        self.close()

    def close(self) -> None:
        """Both heaters off (the model keeps its state)."""
        self.Q1(0)
        self.Q2(0)
        print("TCLab Model disconnected successfully.", file=sys.stderr)

    def update(self, t: float | None = None) -> None:
        """Bring the kit to lab time ``t`` (seconds since construction; default: now if synced)."""
        if t is None:
            if not self.synced:
                return
            t = labtime.time() - self.tstart
        self.tnow = float(t)
        if self.tnow > self.tlast:
            self._kit.advance(
                self.tnow - self.tlast, q1=self._Q1, q2=self._Q2, p1=self._P1, p2=self._P2
            )
            self.tlast = self.tnow

    def quantize(self, T: float) -> float:
        """``T`` °C as the kit's converter reports it (its count below, within the range)."""
        return sensor_reading(T, KitConstants(noise=0.0, quantum=self.constants.quantum))

    def measurement(self, T: float) -> float:
        """A reading of a sensor at ``T`` °C: noise, then the converter."""
        return sensor_reading(T, self.constants, self._rng)

    def _read(self, index: int, name: str) -> float:
        self.update()
        assert self._kit.temperatures is not None
        value = self.measurement(self._kit.temperatures[index])
        if self.debug:
            print(f"{name} -> {value}")
        return value

    @property
    def T1(self) -> float:
        """Sensor 1, °C."""
        return self._read(2, "T1")

    @property
    def T2(self) -> float:
        """Sensor 2, °C."""
        return self._read(3, "T2")

    @property
    def P1(self) -> float:
        """Heater 1's PWM limit, counts of 255 (200 at power-up); setting it clips to 0–255."""
        self.update()
        return self._P1

    @P1.setter
    def P1(self, val: float) -> None:
        self.update()
        self._P1 = clip(val, 0, 255)

    @property
    def P2(self) -> float:
        """Heater 2's PWM limit, counts of 255 (100 at power-up); setting it clips to 0–255."""
        self.update()
        return self._P2

    @P2.setter
    def P2(self, val: float) -> None:
        self.update()
        self._P2 = clip(val, 0, 255)

    def Q1(self, val: float | None = None) -> float:
        """Heater 1 in %: set it to ``val`` clipped to 0–100 (if given); return it."""
        self.update()
        if val is not None:
            self._Q1 = clip(val)
            if self.debug:
                print(f"Q1 <- {self._Q1}")
        return self._Q1

    def Q2(self, val: float | None = None) -> float:
        """Heater 2 in %: set it to ``val`` clipped to 0–100 (if given); return it."""
        self.update()
        if val is not None:
            self._Q2 = clip(val)
            if self.debug:
                print(f"Q2 <- {self._Q2}")
        return self._Q2

    @property
    def U1(self) -> float:
        """Heater 1 in %, as a property."""
        return self.Q1()

    @U1.setter
    def U1(self, val: float) -> None:
        self.Q1(val)

    @property
    def U2(self) -> float:
        """Heater 2 in %, as a property."""
        return self.Q2()

    @U2.setter
    def U2(self, val: float) -> None:
        self.Q2(val)

    def LED(self, val: float = 100) -> float:
        """The LED's brightness in % (the model has no light): ``val`` clipped to 0–100."""
        self.update()
        self._led = clip(val)
        return self._led

    def scan(self) -> tuple[float, float, float, float]:
        """``(T1, T2, Q1, Q2)`` at one instant."""
        self.update()
        assert self._kit.temperatures is not None
        _, _, s1, s2 = self._kit.temperatures
        return (self.measurement(s1), self.measurement(s2), self._Q1, self._Q2)
