"""Which heater and sensor a run's identified model is of, and the loops it may tune.

A run identifies one pair (:mod:`thermolab.runner.pair`): its settings' ``input``
and ``output``, ``u`` and ``y`` for a run from before pairs existed (and for a
closed-loop run, whose methods identify the run's own ``u`` and ``y``). A model
tunes only a loop on that same pair: a kit's Q2 -> T2 model is not the Q1/T1
loop's, however trusted it looks (:func:`check_loop_model`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from thermolab.errors import ModelPairError
from thermolab.rigs import RigInfo
from thermolab.runner import IOPair
from thermolab.runner.pair import STANDARD_INPUT, STANDARD_OUTPUT

__all__ = ["check_loop_model", "model_pair", "output_limit"]


def model_pair(settings: Mapping[str, Any] | None) -> IOPair:
    """The pair a run with these settings identified (``u``/``y`` if they do not say).

    >>> model_pair({"input": "q2", "output": "t2"}), model_pair({}).standard
    (IOPair(input='q2', output='t2'), True)
    """
    settings = settings or {}
    return IOPair(
        str(settings.get("input") or STANDARD_INPUT), str(settings.get("output") or STANDARD_OUTPUT)
    )


def check_loop_model(
    info: RigInfo, settings: Mapping[str, Any] | None, heater: str, sensor: str, run_id: int
) -> IOPair:
    """The run's model pair, if it is the loop's ``heater``/``sensor`` (one the rig pairs).

    Raises
    ------
    LoopPairNotOnRigError
        For a loop the rig does not have (422 ``loop_pair_not_on_rig``).
    ModelPairError
        For a model of another pair (422 ``model_pair_mismatch``).
    """
    info.check_loop_pair(heater, sensor)
    pair = model_pair(settings)
    if (pair.input, pair.output) != (heater, sensor):
        raise ModelPairError(
            f"run {run_id} identified {pair.input} -> {pair.output}, not the loop's "
            f"{heater} -> {sensor}: tune it with a run that identified {heater} -> {sensor}"
        )
    return pair


def output_limit(info: RigInfo, pair: IOPair) -> float | None:
    """The limit a set point of the pair's output must stay below."""
    if pair.output == STANDARD_OUTPUT:
        return info.output_limit
    return info.outputs[pair.output].limit
