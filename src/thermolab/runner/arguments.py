"""The checks of an :class:`~thermolab.runner.Experiment`'s arguments, before the run exists.

Its schedule (``dt``, ``samples``, the input's source, the lateness
tolerance), its controller against its pair, the channels it records against its recorder's, and its
identifiers: each raises :class:`~thermolab.errors.InvalidParameterError`
saying what is wrong, so a bad run is refused before the rig is touched.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from thermolab.errors import InvalidParameterError
from thermolab.records import RUN_CHANNELS, ChannelSpec, channel_names
from thermolab.runner.closed_loop import ControlLoop
from thermolab.runner.inputs import IdentifierLike, InputSignal
from thermolab.runner.pair import IOPair
from thermolab.runner.recorder import Recorder

__all__ = ["check_channels", "check_controller", "check_schedule", "checked_identifiers"]


def check_schedule(
    dt: float,
    samples: int,
    signal: InputSignal | None,
    set_point: float | None,
    late_tolerance: float | None,
) -> float:
    """Check the run's schedule and input source; return the lateness tolerance (``dt / 10``)."""
    if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
        raise InvalidParameterError(f"dt must be a positive number of seconds, got {dt!r}")
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 1:
        raise InvalidParameterError(f"samples must be an integer >= 1, got {samples!r}")
    if signal is not None and set_point is not None:
        raise InvalidParameterError("give either a signal or a set point, not both")
    if late_tolerance is None:
        late_tolerance = dt / 10.0
    if not (math.isfinite(late_tolerance) and late_tolerance >= 0):
        raise InvalidParameterError(
            f"late_tolerance must be a number of seconds >= 0, got {late_tolerance!r}"
        )
    return late_tolerance


def check_controller(controller: object, pair: IOPair) -> None:
    """Check that a closed loop (if any) is a :class:`ControlLoop` on the standard pair."""
    if controller is not None and not pair.standard:
        raise InvalidParameterError(f"a closed loop controls u and y, not {pair}")
    if controller is not None and not isinstance(controller, ControlLoop):
        raise InvalidParameterError(
            f"controller must be a ControlLoop, got {type(controller).__name__}"
        )


def check_channels(channels: tuple[ChannelSpec, ...], recorder: Recorder | None) -> None:
    """Check that no extra channel is taken or repeated, and the recorder writes the run's."""
    names = channel_names(channels)
    for name in names[len(RUN_CHANNELS) :]:
        if names.count(name) > 1:
            raise InvalidParameterError(
                f"extra channel {name!r} is taken or repeated; a run's channels are "
                f"{', '.join(names)}"
            )
    recorded = getattr(recorder, "channels", RUN_CHANNELS)
    if recorder is not None and channel_names(recorded) != channel_names(channels):
        raise InvalidParameterError(
            f"the recorder writes the channels {','.join(channel_names(recorded))} but "
            f"the run has {','.join(names)}; give the recorder channels=Experiment.channels"
        )


def checked_identifiers(
    identifiers: Mapping[str, IdentifierLike] | None,
) -> dict[str, IdentifierLike]:
    """The run's identifiers by name, each checked to have ``update``/``finish``/``to_dict``."""
    checked = dict(identifiers or {})
    for name, ident in checked.items():
        if not isinstance(ident, IdentifierLike):
            raise InvalidParameterError(
                f"identifier {name!r} ({type(ident).__name__}) lacks update/finish/to_dict"
            )
    return checked
