"""The TCLab kit's two-heater twin (``sim:kit``): both heaters, both sensors.

:class:`KitTwinRig` is a rig on :class:`thermolab.kit_physics.KitPhysics`, the
published two-heater energy balance that the offline
:class:`thermolab.tclab.TCLabModel` runs too: heater 1 and sensor 1 are its
primary pair, heater 2 (``q2``) and sensor 2 (``t2``) its further channels, as a
real kit declares them (:func:`thermolab.rigs.tclab.tclab_info`). Readings
carry the kit's noise and its converter's quantisation
(:func:`thermolab.kit_physics.sensor_reading`); ``realism=False`` reads the
sensors' exact temperatures.

The ``sim:tclab`` preset is a different twin: the kit's heater 1 and sensor 1
as the paper's first-order model with a dead time, whose figures many
identification examples rely on.
"""

from __future__ import annotations

import dataclasses
import random

from thermolab.errors import InvalidParameterError
from thermolab.kit_physics import KitConstants, KitPhysics, sensor_reading
from thermolab.rigs.base import BaseRig
from thermolab.rigs.clock import Clock, RealClock
from thermolab.rigs.contract import Reading, RigInfo
from thermolab.rigs.tclab import HEATER_2, kit_sensor_2

__all__ = ["KIT_MAX_TEMPERATURE", "KitTwinRig", "kit_twin_info"]

#: The twin's over-temperature cut-off, °C: a kit's (``TCLabRig``'s ``max_temperature``).
KIT_MAX_TEMPERATURE = 90.0


def kit_twin_info(output_limit: float | None = KIT_MAX_TEMPERATURE) -> RigInfo:
    """Return the :class:`RigInfo` of the kit's twin, without opening it.

    Examples
    --------
    >>> info = kit_twin_info()
    >>> info.name, info.input_unit, list(info.inputs), list(info.outputs)
    ('twin:kit', '%', ['q2'], ['t2'])
    """
    limit = KIT_MAX_TEMPERATURE if output_limit is None else float(output_limit)
    return RigInfo(
        name="twin:kit",
        kind="twin",
        input_min=0.0,
        input_max=100.0,
        input_unit="%",
        output_unit="degC",
        safe_input=0.0,
        output_limit=limit,
        description="The TCLab kit's twin: heaters 1 and 2 (0-100 %), sensors 1 and 2 (°C), "
        "the published two-heater energy balance.",
        further_inputs=(HEATER_2,),
        further_outputs=(kit_sensor_2(limit),),
    )


class KitTwinRig(BaseRig):
    """The kit's twin as a rig: heater 1 in, sensor 1 out; heater 2, sensor 2 further.

    Parameters
    ----------
    clock : Clock, optional
        The clock its physics follows (default :class:`RealClock`); a
        :class:`~thermolab.rigs.VirtualClock` or a lab's speed-up runs it faster.
    seed : int, optional
        Seeds the sensors' noise.
    realism : bool
        ``True``: readings have the kit's noise and quantisation.
    output_limit : float, optional
        Over-temperature cut-off of each sensor, °C (default 90, as the kit).

    Examples
    --------
    >>> from thermolab.rigs import VirtualClock
    >>> clock = VirtualClock()
    >>> with KitTwinRig(clock=clock, realism=False) as rig:
    ...     rig.power_on()
    ...     _ = rig.set_channel("q2", 80.0)
    ...     clock.sleep_until(600.0)
    ...     reading = rig.read()
    >>> round(reading.value, 1) < round(reading.further["t2"], 1)  # heater 2 heats sensor 2 most
    True
    >>> rig.level("q2")  # closing put heater 2 off
    0.0
    """

    def __init__(
        self,
        *,
        clock: Clock | None = None,
        seed: int | None = None,
        realism: bool = True,
        output_limit: float | None = KIT_MAX_TEMPERATURE,
    ) -> None:
        clock = clock if clock is not None else RealClock()
        super().__init__(kit_twin_info(output_limit), clock)
        constants = KitConstants()
        self._constants = constants if realism else dataclasses.replace(constants, noise=0.0)
        self._realism = realism
        self._rng = random.Random(seed)
        self._kit = KitPhysics(self._constants)
        self._t = clock.now()
        self._q1 = self._q2 = 0.0

    def _advance(self) -> float:
        """Bring the physics to the instant of the operation in progress; return it.

        An instant before the last one (a late call for an earlier sample)
        acts at the last one: the heat balance never runs backwards.
        """
        t = max(self._instant(), self._t)
        c = self._constants
        self._kit.advance(t - self._t, q1=self._q1, q2=self._q2, p1=c.p1, p2=c.p2)
        self._t = t
        return t

    def _apply_input(self, u: float) -> float:
        self._advance()
        self._q1 = u
        return u

    def _set_further_input(self, name: str, value: float) -> float:
        # HEATER_2 is the one further input the kit declares.
        self._advance()
        self._q2 = value
        return value

    def _further_level(self, name: str) -> float:
        return self._q2

    def _read_output(self) -> Reading:
        t = self._advance()
        temperatures = self._kit.temperatures
        assert temperatures is not None  # KitPhysics starts them at the ambient
        sensor_1, sensor_2 = temperatures[2], temperatures[3]
        if self._realism:
            sensor_1 = sensor_reading(sensor_1, self._constants, self._rng)
            sensor_2 = sensor_reading(sensor_2, self._constants, self._rng)
        return Reading(sensor_1, t, {"t2": sensor_2})

    def _make_safe(self) -> None:
        # Both heaters off: heater 2 left on would heat the next run's kit (issue #23).
        self._advance()
        self._q1 = self._q2 = 0.0

    def _release(self) -> None:
        pass

    @property
    def applied_input(self) -> float:
        """Heater 1's level now (0 unless powered), %."""
        return self._q1


def check_kit_options(options: dict[str, object]) -> None:
    """Refuse the twin options the kit's twin does not take: it takes realism, output_limit.

    Raises
    ------
    InvalidParameterError
        Naming the refused options.
    """
    unknown = sorted(set(options) - {"realism", "output_limit"})
    if unknown:
        raise InvalidParameterError(
            f"the kit's twin (sim:kit) takes the options realism and output_limit, "
            f"not {', '.join(unknown)}"
        )
