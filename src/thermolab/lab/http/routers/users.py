"""Routes of the accounts (teachers), and of a user's own password."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response, status

from thermolab.errors import AccessDeniedError, InvalidParameterError
from thermolab.lab.accounts.security import AuthenticationError, normalize_username
from thermolab.lab.accounts.users import Principal
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, UserDep, Username, documented_errors
from thermolab.lab.http.schemas import NewUserIn, PasswordIn, UserOut

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


@router.get(
    "/users",
    response_model=list[UserOut],
    tags=["users"],
    summary="All accounts",
    responses=documented_errors(403),
)
def list_users(who: UserDep, lab: LabDep) -> list[UserOut]:
    """Every account (teachers only)."""
    who.require_teacher("list accounts")
    return [UserOut.of(u) for u in lab.users.list()]


@router.post(
    "/users",
    response_model=UserOut,
    status_code=status.HTTP_201_CREATED,
    tags=["users"],
    summary="Create an account",
    responses=documented_errors(403, 409, 422),
)
def add_user(body: NewUserIn, who: UserDep, lab: LabDep) -> UserOut:
    """Create an account (teachers only)."""
    who.require_teacher("create accounts")
    user = lab.users.add(body.username, body.password, body.role, body.display_name)
    lab.names.forget()
    return UserOut.of(user)


@router.delete(
    "/users/{username}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["users"],
    summary="Remove an account",
    responses=documented_errors(403, 404, 409),
)
def remove_user(username: Username, who: UserDep, lab: LabDep) -> Response:
    """Remove an account with its sessions, queue places and runs (teachers only)."""
    who.require_teacher("remove accounts")
    if _same_user(username, who):
        raise AccessDeniedError("you cannot remove your own account; ask another teacher")
    lab.remove_user(username)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.put(
    "/users/{username}/password",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["users"],
    summary="Change a password",
    responses=documented_errors(403, 404, 422, 429),
)
def change_password(
    username: Username,
    body: PasswordIn,
    who: UserDep,
    lab: LabDep,
    request: Request,
) -> Response:
    """Change your own password, or anyone's as a teacher; give your current password.

    Re-authentication (ASVS 4.0 V2.1.6, V3.7.1): the acting user's current
    password is required in ``currentPassword`` in both cases, so a stolen
    session alone cannot take over an account. Every other session of the
    account ends.
    """
    if who.token_id is not None:
        # Re-authentication means a person with the password: a script's token never will do.
        raise AccessDeniedError("an API token cannot change passwords; log in with your password")
    own = _same_user(username, who)
    if not own and not who.is_teacher:
        raise AccessDeniedError("you may only change your own password")
    if body.current_password is None:
        raise InvalidParameterError(
            "currentPassword (your own current password) is required to change a password"
        )
    # The same delays as a login: a stolen session must not become a password oracle.
    address = request.client.host if request.client is not None else "unknown"
    lab.throttle.check(who.username, address)
    try:
        lab.users.verify(who.username, body.current_password)
    except AuthenticationError:
        lab.throttle.record(who.username, address, success=False)
        raise AccessDeniedError("your current password is wrong") from None
    lab.throttle.record(who.username, address, success=True)
    if not own:
        lab.users.get(username)
    lab.users.set_password(username, body.password, keep_session=who.session_id if own else None)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


def _same_user(username: str, who: Principal) -> bool:
    try:
        return normalize_username(username) == who.username
    except InvalidParameterError:
        return False
