"""What a START decides and stores, the same for a run in-process or on a rig host.

Both STARTs (:meth:`.service.RunService.start`,
:class:`thermolab.lab.agents.RemoteRuns`) plan the run on the rig's published
range here (:func:`plan_start`), before they take the rig's lock, then store it
in the locked transaction of the controller's turn (:func:`store_start`).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import timedelta

from thermolab.errors import InvalidParameterError
from thermolab.lab.access import AccessService
from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import LabConfig
from thermolab.lab.rigs.devices import DeviceHub, PublishedRig
from thermolab.lab.runs.request import RunPlan, RunRequest, check_run_length, plan_run
from thermolab.lab.runs.store import add_run, run_channels
from thermolab.records import ChannelSpec
from thermolab.runner import check_pair

__all__ = ["StartPlan", "plan_on_rig", "plan_start", "store_start"]


@dataclass(frozen=True, slots=True)
class StartPlan:
    """What a START decides before it stores the run, in-process or on a rig host."""

    request: RunRequest  #: as the controller asked
    speedup: float | None  #: the rig's pace (its published ``speedup``)
    plan: RunPlan  #: the checked request and its identifiers (:func:`.request.plan_run`)
    channels: tuple[ChannelSpec, ...]  #: in the rig's units (a closed loop adds its own)


def plan_on_rig(
    config: LabConfig, hub: DeviceHub, rig_id: str, request: RunRequest
) -> tuple[RunPlan, PublishedRig]:
    """:func:`.request.plan_run` on the rig: its published input range (its pair's input's, a
    further one), its kind's typical dead time as the live methods' delay. The pair first
    (:func:`~thermolab.runner.check_pair`), open loop only (a closed loop names its own)."""
    published, rig = hub.published(rig_id), config.rig(rig_id)
    pair = check_pair(info := rig.rig_spec.describe(), request.input, request.output)
    if not pair.standard and request.control is not None:
        raise InvalidParameterError(f"the pair {pair} is open loop only")
    limits = pair.limits(info, (published.input_min, published.input_max))
    return plan_run(request, limits, rig.rig_spec.typical_dead_time), published


def plan_start(config: LabConfig, hub: DeviceHub, rig_id: str, request: RunRequest) -> StartPlan:
    """Check a START on the rig: the plan, the length the rig allows, the channels.

    Both STARTs (:meth:`.service.RunService.start`, :class:`thermolab.lab.agents.RemoteRuns`)
    decide it here, before they take the rig's lock. Errors: :func:`.request.plan_run`,
    :func:`.request.check_run_length`.
    """
    plan, published = plan_on_rig(config, hub, rig_id, request)
    check_run_length(request, rig_id, config, published.speedup)  # the rig's own, at once
    channels = run_channels(published.input_unit, published.output_unit)
    return StartPlan(request, published.speedup, plan, channels)


def store_start(
    config: LabConfig,
    access: AccessService,
    rig_id: str,
    who: Principal,
    start: StartPlan,
    channels: tuple[ChannelSpec, ...],
) -> tuple[int, int]:
    """Store the run in the locked transaction of ``who``'s turn; ``(run id, turn id)``.

    A course's slot going on now may lower the longest run: it is read in the
    same transaction, so a slot that begins while the START is decided counts.

    ``AccessDeniedError`` when ``who`` does not control the rig;
    :func:`.request.check_run_length`'s and :func:`.store.add_run`'s errors.
    """
    with access.controlled(rig_id, who, "start a run") as turn:
        limits = turn.course_limits()
        length = check_run_length(start.request, rig_id, config, start.speedup, limits)
        meta = {
            "operating_point": start.plan.operating_point.to_dict(),
            # The run's planned end: the queue's estimated wait counts it.
            "ends_at": (turn.now + timedelta(seconds=length)).isoformat(),
        }
        run_id = add_run(
            turn.session,
            turn.control,
            who,
            turn.now,
            settings=start.plan.settings,
            meta=meta,
            channels=channels,
        )
        return run_id, turn.control.id
