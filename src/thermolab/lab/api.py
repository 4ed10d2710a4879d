"""The routes of the lab's HTTP API, under ``/api``.

Every route but ``POST /api/session`` needs a logged-in user (401 otherwise).
Routes are plain functions: FastAPI runs them in its thread pool, and each
opens its own short database transactions.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Query, Request, Response, Security, status
from fastapi.responses import JSONResponse, StreamingResponse
from fastapi.security import APIKeyCookie

from thermolab.errors import AccessDeniedError, InvalidParameterError
from thermolab.lab.schemas import (
    ControlSessionOut,
    CredentialsIn,
    ErrorOut,
    ExtendIn,
    InputIn,
    InputOut,
    KickIn,
    NewUserIn,
    PasswordIn,
    RigOut,
    RunIn,
    RunOut,
    ServiceIn,
    SessionOut,
    UserOut,
    ValidationErrorOut,
)
from thermolab.lab.security import AuthenticationError, normalize_username
from thermolab.lab.service import Lab
from thermolab.lab.users import Principal

__all__ = ["COOKIE_NAME", "current_user", "get_lab", "router"]

COOKIE_NAME = "thermolab_session"

_cookie = APIKeyCookie(
    name=COOKIE_NAME,
    auto_error=False,
    description="Session cookie set by POST /api/session.",
)


def _errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    shown: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        model = ValidationErrorOut if code == 422 else ErrorOut
        shown[code] = {"model": model}
    return shown


def get_lab(request: Request) -> Lab:
    """Return the :class:`~thermolab.lab.service.Lab` the app serves."""
    lab: Lab = request.app.state.lab
    return lab


LabDep = Annotated[Lab, Depends(get_lab)]


def current_user(lab: LabDep, token: Annotated[str | None, Security(_cookie)]) -> Principal:
    """Return the logged-in user of the request.

    Raises
    ------
    AuthenticationError
        Without a live session (HTTP 401).
    """
    if not token:
        raise AuthenticationError(
            "not logged in: POST /api/session with your user name and password"
        )
    principal = lab.sessions.resolve(token)
    if principal is None:
        raise AuthenticationError("your session has ended; log in again")
    return principal


UserDep = Annotated[Principal, Depends(current_user)]
RigId = Annotated[str, Path(min_length=1, max_length=64, description="the rig's id")]

router = APIRouter(prefix="/api")
_authed = APIRouter(dependencies=[Depends(current_user)], responses=_errors(401))


# -- session -------------------------------------------------------------------------------------


@router.post(
    "/session",
    response_model=SessionOut,
    tags=["session"],
    summary="Log in",
    responses=_errors(401, 422, 429),
)
def login(body: CredentialsIn, request: Request, response: Response, lab: LabDep) -> SessionOut:
    """Check the user name and password and open a session (sets the session cookie).

    Attempts are limited per user name and per client address (429 with
    Retry-After).
    """
    address = request.client.host if request.client is not None else "unknown"
    key = body.username.strip().lower()
    lab.throttle.check(key, address)
    try:
        user = lab.users.verify(body.username, body.password)
    except AuthenticationError:
        lab.throttle.record(key, address, success=False)
        raise
    lab.throttle.record(key, address, success=True)
    lab.sessions.end(request.cookies.get(COOKIE_NAME))
    token, principal = lab.sessions.create(
        user, client_address=address, user_agent=request.headers.get("user-agent")
    )
    policy = lab.config.access
    secure = policy.cookie_secure == "always" or (
        policy.cookie_secure == "auto" and request.url.scheme == "https"
    )
    response.set_cookie(
        COOKIE_NAME,
        token,
        max_age=int(policy.session_lifetime),
        path="/",
        httponly=True,
        samesite=policy.cookie_samesite,
        secure=secure,
    )
    return SessionOut.of(principal)


@_authed.get("/session", response_model=SessionOut, tags=["session"], summary="Who am I")
def whoami(who: UserDep) -> SessionOut:
    """Return the logged-in user."""
    return SessionOut.of(who)


@_authed.delete(
    "/session", status_code=status.HTTP_204_NO_CONTENT, tags=["session"], summary="Log out"
)
def logout(request: Request, lab: LabDep) -> Response:
    """End the session and clear its cookie."""
    lab.sessions.end(request.cookies.get(COOKIE_NAME))
    response = Response(status_code=status.HTTP_204_NO_CONTENT)
    response.delete_cookie(COOKIE_NAME, path="/", httponly=True)
    return response


# -- rigs ------------------------------------------------------------------------------------------


@_authed.get("/rigs", response_model=list[RigOut], tags=["rigs"], summary="All rigs")
def list_rigs(who: UserDep, lab: LabDep) -> list[RigOut]:
    """Every rig with its state, limits and access as the caller sees them (a glance at
    the list is neither a heartbeat nor watching: it changes no watcher count).
    """
    return [RigOut.of(view) for view in lab.access.views(who)]


@_authed.get(
    "/rigs/{rig_id}",
    response_model=RigOut,
    tags=["rigs"],
    summary="One rig",
    responses=_errors(404),
)
def get_rig(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """A rig as the caller sees it; counts as the caller's heartbeat for the rig (and as
    watching it, like the live socket; listing every rig does not).
    """
    return RigOut.of(lab.access.view(rig_id, who))


@_authed.post(
    "/rigs/{rig_id}/control",
    response_model=RigOut,
    tags=["access"],
    summary="Ask for control",
    responses=_errors(404, 409),
)
def request_control(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Take control of a free rig or join its queue (asking again changes nothing)."""
    return RigOut.of(lab.access.request_control(rig_id, who))


@_authed.delete(
    "/rigs/{rig_id}/control",
    response_model=RigOut,
    tags=["access"],
    summary="Release control or leave the queue",
    responses=_errors(404),
)
def release_control(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Give up control (the next in the queue gets it at once) or leave the queue."""
    return RigOut.of(lab.access.release(rig_id, who))


@_authed.post(
    "/rigs/{rig_id}/heartbeat",
    response_model=RigOut,
    tags=["access"],
    summary="I am still here",
    responses=_errors(404),
)
def heartbeat(rig_id: RigId, who: UserDep, lab: LabDep) -> RigOut:
    """Keep the caller's control or queue place alive (any request for the rig does too)."""
    return RigOut.of(lab.access.heartbeat(rig_id, who))


@_authed.post(
    "/rigs/{rig_id}/control/extend",
    response_model=RigOut,
    tags=["teachers"],
    summary="Extend or cut the controller's time",
    responses=_errors(403, 404, 409, 422),
)
def extend_control(rig_id: RigId, body: ExtendIn, who: UserDep, lab: LabDep) -> RigOut:
    """Move the controller's time limit by ``seconds`` (negative cuts it; teachers only)."""
    return RigOut.of(lab.access.extend(rig_id, who, body.seconds))


@_authed.post(
    "/rigs/{rig_id}/control/kick",
    response_model=RigOut,
    tags=["teachers"],
    summary="End a user's turn or queue place",
    responses=_errors(403, 404, 409, 422),
)
def kick(rig_id: RigId, who: UserDep, lab: LabDep, body: KickIn | None = None) -> RigOut:
    """End the controller's turn, or remove ``username`` from the queue (teachers only)."""
    return RigOut.of(lab.access.kick(rig_id, who, body.username if body is not None else None))


@_authed.put(
    "/rigs/{rig_id}/service",
    response_model=RigOut,
    tags=["teachers"],
    summary="Take a rig in or out of service",
    responses=_errors(403, 404, 422),
)
def set_service(rig_id: RigId, body: ServiceIn, who: UserDep, lab: LabDep) -> RigOut:
    """Out of service ends the turn and empties the queue; either way clears a fault."""
    return RigOut.of(lab.set_service(rig_id, who, body.in_service))


@_authed.put(
    "/rigs/{rig_id}/input",
    response_model=InputOut,
    tags=["access"],
    summary="Set the rig's input",
    responses=_errors(403, 404, 422),
)
def set_input(rig_id: RigId, body: InputIn, who: UserDep, lab: LabDep) -> InputOut:
    """Set the input (controller only); ``u`` must be inside the rig's published range."""
    return InputOut.of(lab.apply_input(rig_id, who, body.u))


@_authed.get(
    "/rigs/{rig_id}/control-sessions",
    response_model=list[ControlSessionOut],
    tags=["access"],
    summary="Who controlled the rig, and how each turn ended",
    responses=_errors(404),
)
def control_history(rig_id: RigId, who: UserDep, lab: LabDep) -> list[ControlSessionOut]:
    """Turns at the rig, newest first: all of them for teachers, the caller's own otherwise."""
    lab.config.rig(rig_id)
    rows = lab.access.history(rig_id, None if who.is_teacher else who.user_id)
    return [ControlSessionOut.of(row) for row in rows]


@_authed.get(
    "/rigs/{rig_id}/camera",
    tags=["rigs"],
    summary="The rig's live image",
    response_class=Response,
    responses={200: {"content": {"image/jpeg": {}}}, **_errors(404, 503)},
)
def camera(rig_id: RigId, who: UserDep, lab: LabDep) -> Response:
    """The current image (JPEG): the rig's camera, or for a twin its state drawn (lamp glow
    with the heating power, fan with the cooling, the output).
    """
    image = lab.camera(rig_id)
    lab.presence.touch(rig_id, who.username)  # looking at the rig is watching it
    return Response(image, media_type="image/jpeg", headers={"Cache-Control": "no-store"})


# -- runs ------------------------------------------------------------------------------------------

RunId = Annotated[int, Path(ge=1, description="the run's number")]


@_authed.post(
    "/rigs/{rig_id}/runs",
    response_model=RunOut,
    status_code=status.HTTP_201_CREATED,
    tags=["runs"],
    summary="START a run",
    responses=_errors(403, 404, 409, 422),
)
def start_run(rig_id: RigId, body: RunIn, who: UserDep, lab: LabDep) -> RunOut:
    """Start sampling the rig you control, with a signal or a manual set point and the
    identification methods to run live (change the set point with PUT .../input).
    """
    return RunOut.of(lab.runs.start(rig_id, who, body.request()))


@_authed.post(
    "/rigs/{rig_id}/runs/current/stop",
    response_model=RunOut,
    tags=["runs"],
    summary="END the current run",
    responses=_errors(403, 404, 409),
)
def stop_run(rig_id: RigId, who: UserDep, lab: LabDep) -> RunOut:
    """END: stop after the current sample and compute the final estimates (controller or
    teacher). Returns at once; the run's status changes when it has ended.
    """
    lab.config.rig(rig_id)
    return RunOut.of(lab.runs.stop(rig_id, who))


@_authed.get(
    "/runs",
    response_model=list[RunOut],
    tags=["runs"],
    summary="Runs",
    responses=_errors(403, 404, 422),
)
def list_runs(
    who: UserDep,
    lab: LabDep,
    rig: Annotated[str | None, Query(max_length=64, description="only this rig")] = None,
    user: Annotated[
        str | None,
        Query(
            max_length=64,
            description="only this user's runs (teachers: anyone; students: themselves only)",
        ),
    ] = None,
) -> list[RunOut]:
    """Runs, newest first: your own, or everyone's for a teacher (``user`` narrows it to one
    user; a student naming someone else gets 403, a teacher naming nobody known 404).
    """
    return [RunOut.of(run) for run in lab.runs.list(who, rig, user=user)]


@_authed.get(
    "/runs/{run_id}",
    response_model=RunOut,
    tags=["runs"],
    summary="One run",
    responses=_errors(403, 404),
)
def get_run(run_id: RunId, who: UserDep, lab: LabDep) -> RunOut:
    """A run with each method's latest (or final) estimate."""
    return RunOut.of(lab.runs.get(run_id, who))


@_authed.get(
    "/runs/{run_id}/samples.csv",
    tags=["runs"],
    summary="The run's samples as CSV",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/csv": {}}}, **_errors(403, 404)},
)
def run_samples_csv(run_id: RunId, who: UserDep, lab: LabDep) -> StreamingResponse:
    """Columns ``t,u,y`` first (then ``k``): the file feeds straight into
    ``thermolab identify``.
    """
    lab.runs.get(run_id, who)

    def lines() -> Iterator[str]:
        yield "t,u,y,k\n"
        chunk: list[str] = []
        for k, t, u, y in lab.runs.samples(run_id, who):
            chunk.append(f"{t!r},{u!r},{y!r},{k}\n")
            if len(chunk) >= 1000:
                yield "".join(chunk)
                chunk = []
        yield "".join(chunk)

    return StreamingResponse(
        lines(),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.csv"'},
    )


@_authed.get(
    "/runs/{run_id}/export.json",
    tags=["runs"],
    summary="The run, its samples and every method's results as JSON",
    responses=_errors(403, 404),
)
def run_export(run_id: RunId, who: UserDep, lab: LabDep) -> JSONResponse:
    """Everything stored about a run: settings, samples, trajectories, final estimates."""
    exported = lab.runs.export(run_id, who)
    exported["run"] = RunOut.of(exported["run"]).model_dump(mode="json", by_alias=True)
    return JSONResponse(
        exported,
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.json"'},
    )


# -- users ---------------------------------------------------------------------------------------


def _teacher(who: Principal, action: str) -> None:
    if not who.is_teacher:
        raise AccessDeniedError(f"only a teacher may {action}")


@_authed.get(
    "/users",
    response_model=list[UserOut],
    tags=["users"],
    summary="All accounts",
    responses=_errors(403),
)
def list_users(who: UserDep, lab: LabDep) -> list[UserOut]:
    """Every account (teachers only)."""
    _teacher(who, "list accounts")
    return [UserOut.of(u) for u in lab.users.list()]


@_authed.post(
    "/users",
    response_model=UserOut,
    status_code=status.HTTP_201_CREATED,
    tags=["users"],
    summary="Create an account",
    responses=_errors(403, 409, 422),
)
def add_user(body: NewUserIn, who: UserDep, lab: LabDep) -> UserOut:
    """Create an account (teachers only)."""
    _teacher(who, "create accounts")
    return UserOut.of(lab.users.add(body.username, body.password, body.role))


@_authed.delete(
    "/users/{username}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["users"],
    summary="Remove an account",
    responses=_errors(403, 404, 409),
)
def remove_user(
    username: Annotated[str, Path(max_length=64)], who: UserDep, lab: LabDep
) -> Response:
    """Remove an account with its sessions, queue places and runs (teachers only)."""
    _teacher(who, "remove accounts")
    if _same_user(username, who):
        raise AccessDeniedError("you cannot remove your own account; ask another teacher")
    lab.remove_user(username)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@_authed.put(
    "/users/{username}/password",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["users"],
    summary="Change a password",
    responses=_errors(403, 404, 422),
)
def change_password(
    username: Annotated[str, Path(max_length=64)],
    body: PasswordIn,
    who: UserDep,
    lab: LabDep,
) -> Response:
    """Change your own password (give the current one), or anyone's as a teacher.

    Every other session of the account ends.
    """
    if _same_user(username, who):
        if body.current_password is None:
            raise InvalidParameterError("currentPassword is required to change your own password")
        try:
            lab.users.verify(who.username, body.current_password)
        except AuthenticationError:
            raise AccessDeniedError("the current password is wrong") from None
    elif not who.is_teacher:
        raise AccessDeniedError("you may only change your own password")
    else:
        lab.users.get(username)
    keep = who.session_id if _same_user(username, who) else None
    lab.users.set_password(username, body.password, keep_session=keep)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


def _same_user(username: str, who: Principal) -> bool:
    try:
        return normalize_username(username) == who.username
    except InvalidParameterError:
        return False


router.include_router(_authed)
