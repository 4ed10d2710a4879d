"""How a run's identifiers treat the rig's operating point: the lab's policy.

``"auto"`` looks at the rig first (:meth:`OperatingPointPolicy.at_rest`) and
chooses ``"initial"`` for a rig at rest and ``"fit"`` for a warm one; the
choice and its reason are stored with the run (:class:`OperatingPoint`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import timedelta
from typing import Any

from sqlalchemy import select

from thermolab.errors import InvalidParameterError
from thermolab.lab.access import AccessService
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import Command, Run
from thermolab.lab.devices import DeviceHub
from thermolab.lab.runs.request import OFFSET_METHODS

__all__ = ["OperatingPoint", "OperatingPointPolicy"]


@dataclass(frozen=True, slots=True)
class OperatingPoint:
    """How a run's identifiers handle the operating point, and why (stored with the run).

    Attributes
    ----------
    asked : str or float
        The request's ``offset`` (``"auto"`` unless the user chose).
    used : str, float or None
        The mode the identifiers were built with; ``None`` when no chosen
        method regresses on the output (the step response finds its own
        baseline).
    at_rest : bool or None
        Whether the lab judged the rig at rest at START (``None``: not judged).
    reason : str
        The judgement and the choice, in words (shown to the user).

    Examples
    --------
    >>> OperatingPoint("auto", "fit", False, "run 3 ended 12 s ago").to_dict()["used"]
    'fit'
    """

    asked: str | float
    used: str | float | None
    at_rest: bool | None
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (``asked``, ``used``, ``atRest``, ``reason``)."""
        return {
            "asked": self.asked,
            "used": self.used,
            "atRest": self.at_rest,
            "reason": self.reason,
        }


class OperatingPointPolicy:
    """Judges whether a rig is at rest and chooses the run's operating point.

    Parameters
    ----------
    db : Database
    clock : LabClock
    access : AccessService
    hub : DeviceHub
    config : LabConfig
        The rigs' cool-down policies (they say when a rig counts as at rest).
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        access: AccessService,
        hub: DeviceHub,
        config: LabConfig,
    ) -> None:
        self._db = db
        self._clock = clock
        self._access = access
        self._hub = hub
        self._config = config

    def choose(self, rig_id: str, asked: str | float, methods: Sequence[str]) -> OperatingPoint:
        """Decide how a run's identifiers treat the rig's operating point.

        ``"initial"`` (the default of :mod:`thermolab.ident`) takes the first
        sample as the equilibrium at 0 V and removes it. A rig still cooling
        after a previous run (or driven by an input a moment ago) breaks that:
        its first sample is neither an equilibrium nor the output at 0 V, and
        the estimates come out biased or unstable. ``"auto"`` therefore looks at
        the rig first (see :meth:`at_rest`) and takes ``"initial"`` for a rig at
        rest, ``"fit"`` (the constant term estimated with the model) for a warm
        one. An explicit choice is kept; ``"initial"`` on a warm rig is kept with
        a warning in the reason.

        Parameters
        ----------
        rig_id : str
        asked : str or float
            The request's ``offset``.
        methods : sequence of str
            The run's methods (only LSM, block LSM, MALSM and WLSM use an offset).

        Returns
        -------
        OperatingPoint

        Raises
        ------
        InvalidParameterError
            For an explicit offset when no chosen method uses one.
        """
        users = [m for m in methods if m in OFFSET_METHODS]
        if not users:
            if asked != "auto":
                raise InvalidParameterError(
                    f"offset is a setting of {', '.join(OFFSET_METHODS)}, none of which is among "
                    f"the methods ({', '.join(methods)}); the step response finds its own baseline"
                )
            return OperatingPoint(
                asked, None, None, "no chosen method uses it (the step response finds its baseline)"
            )
        rest, why = self.at_rest(rig_id)
        if asked == "auto":
            if rest:
                return OperatingPoint(
                    asked,
                    "initial",
                    True,
                    f"initial: the rig is at rest ({why}), so its first sample is the "
                    "equilibrium at the safe input and is removed",
                )
            return OperatingPoint(
                asked,
                "fit",
                False,
                f"fit: the rig is not at rest ({why}), so its first sample is no equilibrium; "
                "the operating point is estimated with the model",
            )
        if asked == "initial" and not rest:
            return OperatingPoint(
                asked,
                asked,
                False,
                f"initial, as asked, although the rig is not at rest ({why}): the model may be "
                "biased or unstable; 'fit' estimates the operating point instead",
            )
        state = "at rest" if rest else "not at rest"
        return OperatingPoint(asked, asked, rest, f"{asked}, as asked (the rig is {state}: {why})")

    def at_rest(self, rig_id: str) -> tuple[bool, str]:
        """Whether the rig rests at its equilibrium at the safe input, and why (in words).

        A rig is *not* at rest when any of these holds, checked in this order:

        1. its input is not the safe input now;
        2. a run on it ended, or an input other than the safe one was applied
           to it, within the last ``cooldown.max_seconds`` (the longest the lab
           ever waits for a rig to cool) — and, when the rig cools down between
           turns, since the current turn began (the cool-down before it settled
           what came earlier);
        3. its latest reading is further than ``cooldown.tolerance`` from its
           ambient (the configured one, or the first reading of the rig powered
           on cold).

        Rule 2 needs no threshold, so a rig taken straight from one run to the
        next is always seen as warm, whatever its output's unit and scale.
        """
        cfg = self._config.rig(rig_id)
        published = self._hub.published(rig_id)
        unit, safe = published.output_unit, published.safe_input
        applied = self._hub.applied(rig_id)
        if applied is not None and applied != safe:
            return False, (
                f"its input is {applied:g} {published.input_unit}, not the safe "
                f"{safe:g} {published.input_unit}"
            )
        now = self._clock.now()
        window = cfg.cooldown.max_seconds
        since = now - timedelta(seconds=window)
        snap = self._access.snapshot(rig_id)
        if cfg.cooldown.enabled and snap.controller is not None:
            since = max(since, snap.controller.started_at)
        with self._db.read() as session:
            ended = session.execute(
                select(Run.id, Run.ended_at)
                .where(Run.rig_id == rig_id, Run.ended_at >= since)
                .order_by(Run.ended_at.desc(), Run.id.desc())
                .limit(1)
            ).first()
            driven = session.execute(
                select(Command.value, Command.at)
                .where(
                    Command.rig_id == rig_id,
                    Command.kind == "input",
                    Command.at >= since,
                    Command.value != safe,
                )
                .order_by(Command.at.desc(), Command.id.desc())
                .limit(1)
            ).first()
        if ended is not None:
            ago = (now - ended.ended_at).total_seconds()
            return False, f"run {ended.id} on it ended {ago:.0f} s ago; it may still be cooling"
        if driven is not None:
            ago = (now - driven.at).total_seconds()
            return False, (
                f"an input of {driven.value:g} {published.input_unit} was applied {ago:.0f} s "
                "ago; it may still be cooling"
            )
        ambient = cfg.cooldown.ambient if cfg.cooldown.ambient is not None else snap.ambient_output
        reading = self._hub.reading(rig_id)
        quiet = f"not driven for {window:g} s"
        if ambient is None or reading is None:
            return True, f"{quiet}; its ambient is not known yet"
        gap = reading[0] - ambient
        tolerance = cfg.cooldown.tolerance
        if abs(gap) > tolerance:
            return False, (
                f"its output {reading[0]:g} {unit} is {abs(gap):g} {unit} from its ambient "
                f"{ambient:g} {unit}, more than the tolerance {tolerance:g} {unit}"
            )
        return True, (
            f"{quiet}, output within {tolerance:g} {unit} of its ambient {ambient:g} {unit}"
        )
