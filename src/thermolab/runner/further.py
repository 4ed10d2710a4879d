"""The further channels of a rig in a run: what every run records of them, and their requests.

A rig declares its further inputs and outputs once
(:attr:`thermolab.rigs.RigInfo.further_inputs`, ``further_outputs``: a kit's
heater 2 and sensor 2). A run records each further output, read with ``y`` at
every sample (``Reading.further``), and each further input declared
``recorded`` at its level after the sample's inputs are applied, as channels
after the standard ones and a closed loop's (:func:`further_channels`). The
twin's fan is not ``recorded``: a closed-loop run records it among its own
channels (:data:`~thermolab.runner.control_requests.FAN_CHANNEL`), as before
further channels were declared.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from thermolab.records import ChannelSpec
from thermolab.rigs import Rig, RigInfo
from thermolab.runner.closed_loop import ControlLoop
from thermolab.runner.control_requests import closed_loop_channels
from thermolab.runner.inputs import ChannelSource

__all__ = ["extra_channels", "further_channels", "further_sources"]


def further_channels(info: RigInfo) -> tuple[ChannelSpec, ...]:
    """The channels every run on the rig ``info`` records besides the standard ones.

    Its further outputs (role ``output``), then its further inputs declared
    ``recorded`` (role ``input``), in declaration order: what a recorder of the
    run declares after a closed loop's channels.

    Examples
    --------
    >>> from thermolab.rigs import tclab_info
    >>> [(c.name, c.unit, c.role) for c in further_channels(tclab_info(None))]
    [('t2', 'degC', 'output'), ('q2', '%', 'input')]
    """
    outputs = tuple(
        ChannelSpec(c.name, c.unit, "output", c.description) for c in info.further_outputs
    )
    inputs = tuple(
        ChannelSpec(c.name, c.unit, "input", c.description)
        for c in info.further_inputs
        if c.recorded
    )
    return (*outputs, *inputs)


def extra_channels(
    rig: object, info: RigInfo, loop: ControlLoop | None, *, fan: bool | None = None
) -> tuple[ChannelSpec, ...]:
    """Every channel a run on the rig records after ``RUN_CHANNELS``, in the run's order.

    A closed loop's (:func:`~thermolab.runner.closed_loop_channels`: its own,
    then the fan when the rig has one; ``loop`` bound first), then the rig's
    further channels (:func:`further_channels`): what the recorder of the run
    declares (``Experiment(...).channels`` after the standard ones, known
    before the rig is sampled). ``rig`` and ``fan`` as for
    :func:`~thermolab.runner.closed_loop_channels` (a rig host's rig is known
    by its spec only: ``rig=None`` and ``fan`` said).

    Examples
    --------
    >>> from thermolab.rigs import tclab_info
    >>> [c.name for c in extra_channels(None, tclab_info(None), None)]
    ['t2', 'q2']
    """
    looped = () if loop is None else closed_loop_channels(rig, loop, fan=fan)
    return (*looped, *further_channels(info))


def further_sources(
    rig: Rig, info: RigInfo, reading: Callable[[], Mapping[str, float]]
) -> tuple[ChannelSource, ...]:
    """A source per further channel the run records, in :func:`further_channels`' order.

    An output's value comes from the sample's reading (``reading()``: the
    further values the sampling loop kept of it), an input's from the rig once
    the sample's inputs are applied.
    """

    def output(name: str) -> Callable[[float, float, float], float]:
        return lambda t, u, y: float(reading().get(name, math.nan))

    def input_level(name: str) -> Callable[[float, float, float], float]:
        return lambda t, u, y: float(rig.level(name))

    return tuple(
        (spec, output(spec.name) if spec.role == "output" else input_level(spec.name))
        for spec in further_channels(info)
    )
