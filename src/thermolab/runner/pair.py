"""The input/output pair a run identifies: which actuator the signal drives, which sensor it reads.

A rig has one standard pair, its input ``u`` and output ``y`` (a kit's heater 1
and sensor 1), and may declare further channels (a kit's heater 2 ``q2`` and
sensor 2 ``t2``, :attr:`thermolab.rigs.RigInfo.further_inputs`). A run
identifies one pair, the standard one unless asked otherwise
(:func:`check_pair`): its input is ``u`` or a further input the run records,
its output ``y`` or a further output. With a further input the run's signal
or manual input drives that input and ``u`` rests at its safe value; the
identifiers are given the pair's samples (:class:`~thermolab.runner.Experiment`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TypeVar

from thermolab.errors import PairChannelUnknownError, PairRoleError
from thermolab.rigs import RigInfo
from thermolab.runner.interlocks import Interlocks

__all__ = ["STANDARD_INPUT", "STANDARD_OUTPUT", "IOPair", "check_pair", "pair_choices"]

T = TypeVar("T")

#: The names of a rig's standard input and output (the record's ``u`` and ``y`` columns).
STANDARD_INPUT = "u"
STANDARD_OUTPUT = "y"


@dataclass(frozen=True, slots=True)
class IOPair:
    """A run's identified pair, by the channels' names in the run's record.

    Examples
    --------
    >>> IOPair().standard, IOPair("q2", "t2").to_dict()
    (True, {'input': 'q2', 'output': 't2'})
    """

    input: str = STANDARD_INPUT
    output: str = STANDARD_OUTPUT

    @property
    def standard(self) -> bool:
        """Whether this is the rig's standard pair (``u``, ``y``)."""
        return self.input == STANDARD_INPUT and self.output == STANDARD_OUTPUT

    @property
    def drives_further(self) -> bool:
        """Whether the run's input drives a further input (not ``u``)."""
        return self.input != STANDARD_INPUT

    def to_dict(self) -> dict[str, str]:
        """``{"input": ..., "output": ...}``."""
        return {"input": self.input, "output": self.output}

    def input_range(self, info: RigInfo) -> tuple[float, float]:
        """The range of the pair's input on the rig ``info`` (checked: :func:`check_pair`)."""
        if not self.drives_further:
            return info.input_range
        channel = info.inputs[self.input]
        return (channel.minimum, channel.maximum)

    def limits(self, info: RigInfo, standard: tuple[float, float]) -> tuple[float, float]:
        """The input range a run's signal is checked against: ``standard`` (``u``'s, as
        published) or the further input's declared range."""
        return self.input_range(info) if self.drives_further else standard

    def rest(self, info: RigInfo) -> float:
        """Where the pair's input rests on the rig ``info`` (safe input, the channel's default)."""
        return info.inputs[self.input].default if self.drives_further else info.safe_input

    def units(self, info: RigInfo) -> tuple[str, str]:
        """The units of the pair's input and output on the rig ``info``."""
        unit_in = info.input_unit if not self.drives_further else info.inputs[self.input].unit
        unit_out = (
            info.output_unit if self.output == STANDARD_OUTPUT else info.outputs[self.output].unit
        )
        return unit_in, unit_out

    def input_problem(self, u: float, info: RigInfo) -> str | None:
        """Why ``u`` must not drive the pair's input on the rig ``info``, or ``None``.

        >>> from thermolab.rigs import tclab_info
        >>> IOPair("q2", "t2").input_problem(120.0, tclab_info(None))
        "input q2 120 % is outside the range of 'TCLab (found automatically)': [0, 100] %"
        """
        if not self.drives_further:
            return Interlocks.check_input(u, info)
        low, high = self.input_range(info)
        if math.isfinite(u) and low <= u <= high:
            return None
        unit = info.inputs[self.input].unit
        return (
            f"input {self.input} {u:g} {unit} is outside the range of {info.name!r}: "
            f"[{low:g}, {high:g}] {unit}"
        )

    def columns(self, u: T, y: T, extra: Mapping[str, T]) -> tuple[T, T]:
        """The pair's input and output among a record's columns (``u``, ``y``, the others)."""
        return (
            extra[self.input] if self.drives_further else u,
            y if self.output == STANDARD_OUTPUT else extra[self.output],
        )

    def output_of(self, y: float, further: Mapping[str, float]) -> float:
        """The pair's output in a sample whose standard output is ``y``."""
        return y if self.output == STANDARD_OUTPUT else float(further.get(self.output, math.nan))


def pair_choices(info: RigInfo) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The inputs and the outputs a run on the rig ``info`` may identify, standard first.

    Examples
    --------
    >>> from thermolab.rigs import tclab_info
    >>> pair_choices(tclab_info(None))
    (('u', 'q2'), ('y', 't2'))
    """
    inputs = (STANDARD_INPUT, *(c.name for c in info.further_inputs if c.recorded))
    outputs = (STANDARD_OUTPUT, *(c.name for c in info.further_outputs))
    return inputs, outputs


def check_pair(info: RigInfo, input: str | None = None, output: str | None = None) -> IOPair:
    """The pair ``input`` → ``output`` on the rig ``info`` (``None``: the standard channel).

    Raises
    ------
    PairChannelUnknownError
        For a name the rig does not declare (422 ``pair_channel_unknown``).
    PairRoleError
        For an input that is no input the run records (a sensor, the twin's
        fan), or an output that is no sensor (422 ``pair_wrong_role``).

    Examples
    --------
    >>> from thermolab.rigs import tclab_info
    >>> check_pair(tclab_info(None), "q2", "t2")
    IOPair(input='q2', output='t2')
    >>> check_pair(tclab_info(None), "t2", "t2")
    Traceback (most recent call last):
    ...
    thermolab.errors.PairRoleError: the pair's input 't2' is an output of ...
    """
    pair = IOPair(input or STANDARD_INPUT, output or STANDARD_OUTPUT)
    inputs, outputs = pair_choices(info)
    known = {*inputs, *outputs, *info.inputs}
    for name in (pair.input, pair.output):
        if name not in known:
            raise PairChannelUnknownError(
                f"rig {info.name!r} has no channel {name!r}; its inputs: {', '.join(inputs)}; "
                f"its outputs: {', '.join(outputs)}"
            )
    if pair.input not in inputs:
        what = "an output" if pair.input in outputs else "an input no run records"
        raise PairRoleError(
            f"the pair's input {pair.input!r} is {what} of rig {info.name!r}; "
            f"the input is one of {', '.join(inputs)}"
        )
    if pair.output not in outputs:
        raise PairRoleError(
            f"the pair's output {pair.output!r} is an input of rig {info.name!r}; "
            f"the output is one of {', '.join(outputs)}"
        )
    return pair
