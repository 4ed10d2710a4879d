"""Routes of the rigs: state, access (control, queue, heartbeat), teachers, input, camera."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Request, Response

from thermolab.lab.access import RigView
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, RigId, UserDep, audit, documented_errors
from thermolab.lab.http.errors import request_language
from thermolab.lab.http.schemas import (
    ControlSessionOut,
    ExtendIn,
    InputIn,
    InputOut,
    KickIn,
    RigOut,
    ServiceIn,
    people_named,
)
from thermolab.lab.http.script_schemas import ChannelIn, ChannelOut, SpeedupIn
from thermolab.lab.service import Lab

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


def _out(view: RigView, lab: Lab) -> RigOut:
    """The rig as answered: the view, with the display names of the people it names."""
    return RigOut.of(view, lab.names.names(people_named(view)))


@router.get("/rigs", response_model=list[RigOut], tags=["rigs"], summary="All rigs")
def list_rigs(who: UserDep, lab: LabDep) -> list[RigOut]:
    """Every rig with its state, limits and access as the caller sees them (a glance at
    the list is neither a heartbeat nor watching: it changes no watcher count).
    """
    return [_out(view, lab) for view in lab.access.views(who)]


@router.get(
    "/rigs/{rig_id}",
    response_model=RigOut,
    tags=["rigs"],
    summary="One rig",
    responses=documented_errors(404),
)
def get_rig(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """A rig as the caller sees it; counts as the caller's heartbeat for the rig (and as
    watching it, like the live socket; listing every rig does not).
    """
    return _out(lab.access.view(rig_id, who), lab)


@router.post(
    "/rigs/{rig_id}/control",
    response_model=RigOut,
    tags=["access"],
    summary="Ask for control",
    responses=documented_errors(403, 404, 409),
)
def request_control(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Take control of a free rig or join its queue (asking again changes nothing).

    A student may ask only for a rig one of their courses uses (403 otherwise;
    a course that lists no rigs uses them all, and so does a student in no course).
    """
    if not who.is_teacher and any(rig.id == rig_id for rig in lab.config.rigs):
        lab.courses.check_rig(who.user_id, rig_id)
    return _out(lab.access.request_control(rig_id, who), lab)


@router.delete(
    "/rigs/{rig_id}/control",
    response_model=RigOut,
    tags=["access"],
    summary="Release control or leave the queue",
    responses=documented_errors(404),
)
def release_control(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Give up control (the next in the queue gets it at once) or leave the queue."""
    return _out(lab.access.release(rig_id, who), lab)


@router.post(
    "/rigs/{rig_id}/heartbeat",
    response_model=RigOut,
    tags=["access"],
    summary="I am still here",
    responses=documented_errors(404),
)
def heartbeat(rig_id: RigId, request: Request, who: UserDep, lab: LabDep) -> RigOut:
    """Keep the caller's control or queue place alive (any request for the rig does too).

    To a caller without the controls the answer says how their last turn ended,
    in the request's language (``Accept-Language``, or the lab's language cookie).
    """
    language = request_language(request.headers, request.cookies)
    return _out(lab.access.heartbeat(rig_id, who, language), lab)


@router.post(
    "/rigs/{rig_id}/control/extend",
    response_model=RigOut,
    tags=["teachers"],
    summary="Extend or cut the controller's time",
    responses=documented_errors(403, 404, 409, 422),
)
def extend_control(rig_id: RigId, body: ExtendIn, who: UserDep, lab: LabDep) -> RigOut:
    """Move the controller's time limit by ``seconds`` (negative cuts it; teachers only)."""
    return _out(lab.access.extend(rig_id, who, body.seconds), lab)


@router.post(
    "/rigs/{rig_id}/control/more-time",
    response_model=RigOut,
    tags=["rigs"],
    summary="Extend one's own turn while nobody waits",
    responses=documented_errors(404, 409),
)
def more_time(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Add 120 s to the caller's own turn: only in its last minute, with the queue empty,
    at most twice a turn — without that bound for a turn asked for with an API token (a
    script) — (409 ``extend_refused`` says which rule stops it)."""
    return _out(lab.access.extend_own(rig_id, who), lab)


@router.put(
    "/rigs/{rig_id}/control/speedup",
    response_model=RigOut,
    tags=["access"],
    summary="Run a twin at one's own speed-up for the turn",
    responses=documented_errors(403, 404, 409, 422),
)
def pace_turn(rig_id: RigId, body: SpeedupIn, who: UserDep, lab: LabDep) -> RigOut:
    """Run the twin at ``speedup`` until the caller's turn ends (controller only): from 1 up
    to the twin's ``twin_speedup``, while no run is going (409; a run keeps its pace).
    Hardware and a rig host's twin keep their own pace (422 ``speedup_refused``, as for a
    speed-up out of range, naming the rig and what it allows)."""
    lab.config.rig(rig_id)  # an unknown rig is a 404
    with lab.access.controlled(rig_id, who, "change the twin's speed-up") as turn:
        lab.hub.pace_turn(rig_id, body.speedup, controller_session=turn.control.id)
    return _out(lab.access.view(rig_id, who), lab)


@router.post(
    "/rigs/{rig_id}/control/kick",
    response_model=RigOut,
    tags=["teachers"],
    summary="End a user's turn or queue place",
    responses=documented_errors(403, 404, 409, 422),
)
def kick(rig_id: RigId, who: UserDep, lab: LabDep, body: KickIn | None = None) -> RigOut:
    """End the controller's turn, or remove ``username`` from the queue (teachers only)."""
    return _out(lab.access.kick(rig_id, who, body.username if body is not None else None), lab)


@router.put(
    "/rigs/{rig_id}/service",
    response_model=RigOut,
    tags=["teachers"],
    summary="Take a rig in or out of service",
    responses=documented_errors(403, 404, 422),
)
def set_service(
    rig_id: RigId, body: ServiceIn, who: UserDep, lab: LabDep, request: Request
) -> RigOut:
    """Out of service ends the turn and empties the queue; either way clears a fault."""
    changed = _out(lab.set_service(rig_id, who, body.in_service), lab)
    audit(lab, who, request, AuditAction.RIG_SERVICE, rig_id, in_service=body.in_service)
    return changed


@router.put(
    "/rigs/{rig_id}/input",
    response_model=InputOut,
    tags=["access"],
    summary="Set the rig's input",
    responses=documented_errors(403, 404, 422),
)
def set_input(rig_id: RigId, body: InputIn, who: UserDep, lab: LabDep) -> InputOut:
    """Set the input (controller only); ``u`` must be inside the rig's published range."""
    return InputOut.of(lab.apply_input(rig_id, who, body.u))


@router.put(
    "/rigs/{rig_id}/channels/{name}",
    response_model=ChannelOut,
    tags=["access"],
    summary="Set one of the rig's further inputs (a kit's heater 2)",
    responses=documented_errors(403, 404, 409, 422),
)
def set_channel(
    rig_id: RigId,
    name: Annotated[
        str,
        Path(
            min_length=1,
            max_length=40,
            pattern=r"^[a-z][a-z0-9_]*$",  # a channel's name (thermolab.records.ChannelSpec)
            description="the input's name, e.g. q2",
        ),
    ],
    body: ChannelIn,
    who: UserDep,
    lab: LabDep,
) -> ChannelOut:
    """Controller only. During a run the level goes to the run, from its next sample on (as
    the fan does); otherwise to the rig now. 422 ``channel_not_on_rig`` for an input the rig
    does not have, ``invalid_parameter`` outside its range; the end of the run and of the
    turn put it back at its declared default.
    """
    return ChannelOut.of(lab.set_channel(rig_id, who, name, body.level))


@router.get(
    "/rigs/{rig_id}/control-sessions",
    response_model=list[ControlSessionOut],
    tags=["access"],
    summary="Who controlled the rig, and how each turn ended",
    responses=documented_errors(404),
)
def control_history(rig_id: RigId, who: UserDep, lab: LabDep) -> list[ControlSessionOut]:
    """Turns at the rig, newest first: all of them for teachers, the caller's own otherwise."""
    lab.config.rig(rig_id)
    rows = lab.access.history(rig_id, None if who.is_teacher else who.user_id)
    return [ControlSessionOut.of(row) for row in rows]


@router.get(
    "/rigs/{rig_id}/camera",
    tags=["rigs"],
    summary="The rig's live image",
    response_class=Response,
    responses={200: {"content": {"image/jpeg": {}}}, **documented_errors(404, 503)},
)
def camera(rig_id: RigId, who: UserDep, lab: LabDep, request: Request) -> Response:
    """The current image (JPEG): the rig's camera, or for a twin its state drawn (lamp glow
    with the heating power, fan with the cooling, the output) in the reader's language.
    """
    image = lab.camera(rig_id, request_language(request.headers, request.cookies))
    lab.presence.touch(rig_id, who.username)  # looking at the rig is watching it
    return Response(image, media_type="image/jpeg", headers={"Cache-Control": "no-store"})
