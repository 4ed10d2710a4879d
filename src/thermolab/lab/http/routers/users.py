"""Routes of the accounts (teachers), and of a user's own password."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response, status

from thermolab.errors import AccessDeniedError, InvalidParameterError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.security import AuthenticationError, normalize_username
from thermolab.lab.accounts.users import Principal
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.http.account_schemas import NewUserIn, PasswordIn, UserOut
from thermolab.lab.http.bodies import In
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    UserDep,
    Username,
    audit,
    client_address,
    documented_errors,
)

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
    """Every account (lab administrators only)."""
    lab.authorize.require_lab(who, Action.ACCOUNTS_READ)
    return [UserOut.of(u) for u in lab.users.list()]


@router.post(
    "/users",
    response_model=UserOut,
    status_code=status.HTTP_201_CREATED,
    tags=["users"],
    summary="Create an account",
    responses=documented_errors(403, 409, 422),
)
def add_user(body: NewUserIn, who: UserDep, lab: LabDep, request: Request) -> UserOut:
    """Create an account (lab administrators only; teachers add students by class list)."""
    lab.authorize.require_lab(who, Action.ACCOUNT_CREATE)
    user = lab.users.add(
        body.username, body.password, body.role, body.display_name, admin=body.admin
    )
    lab.names.forget()
    audit(
        lab,
        who,
        request,
        AuditAction.ACCOUNT_CREATED,
        user.username,
        role=user.role.value,
        admin=user.admin,
    )
    return UserOut.of(user)


@router.delete(
    "/users/{username}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["users"],
    summary="Remove an account",
    responses=documented_errors(403, 404, 409),
)
def remove_user(username: Username, who: UserDep, lab: LabDep, request: Request) -> Response:
    """Remove an account with its sessions, queue places and runs (administrators only)."""
    lab.authorize.require_lab(who, Action.ACCOUNT_REMOVE)
    if _same_user(username, who):
        raise AccessDeniedError("you cannot remove your own account; ask another administrator")
    removed = lab.remove_user(username)
    audit(lab, who, request, AuditAction.ACCOUNT_REMOVED, removed.username)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


class AdminIn(In):
    """Whether the account is a lab administrator."""

    admin: bool


@router.put(
    "/users/{username}/admin",
    response_model=UserOut,
    tags=["users"],
    summary="Make or unmake a lab administrator",
    responses=documented_errors(403, 404, 422),
)
def set_admin(
    username: Username, body: AdminIn, who: UserDep, lab: LabDep, request: Request
) -> UserOut:
    """Make a teacher a lab administrator, or take it back (administrators only)."""
    lab.authorize.require_lab(who, Action.ACCOUNT_ROLE)
    user = lab.users.set_admin(username, body.admin)
    audit(lab, who, request, AuditAction.ACCOUNT_ADMIN, user.username, admin=user.admin)
    return UserOut.of(user)


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
    """Change your own password; an administrator anyone's, a teacher their students'.

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
    if not own:
        lab.authorize.require_person(who, Action.PASSWORD_SET, username)
    if body.current_password is None:
        raise InvalidParameterError(
            "currentPassword (your own current password) is required to change a password"
        )
    # The same delays as a login: a stolen session must not become a password oracle.
    address = client_address(request)
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
    if not own:
        audit(lab, who, request, AuditAction.PASSWORD_SET, normalize_username(username))
    return Response(status_code=status.HTTP_204_NO_CONTENT)


def _same_user(username: str, who: Principal) -> bool:
    try:
        return normalize_username(username) == who.username
    except InvalidParameterError:
        return False
