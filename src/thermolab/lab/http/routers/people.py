"""A person removed for good: ``POST /api/users/{username}/forget`` (administrators).

Their logins, tokens and LMS identities go and their name leaves every row;
their runs, turns and hand-ins stay under a pseudonym for the class's
statistics (``runs: "keep"``) or go with them (``"delete"``). See
:func:`thermolab.lab.accounts.personal_data.forget_person`.
"""

from __future__ import annotations

import secrets
from typing import Literal

from fastapi import APIRouter, Request
from pydantic import Field

from thermolab.errors import AccessDeniedError
from thermolab.lab.accounts.names import username_form
from thermolab.lab.accounts.personal_data import forget_person
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.security import default_password_hasher
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    UserDep,
    Username,
    client_address,
    documented_errors,
)

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


class ForgetIn(In):
    """What happens to the person's runs."""

    runs: Literal["keep", "delete"] = Field(
        description="keep: under a pseudonym, for the class's statistics; delete: with them"
    )


class ForgottenOut(Out):
    """The pseudonym the kept rows now carry."""

    pseudonym: str = Field(description="removed-XXXXXXXX")


@router.post(
    "/users/{username}/forget",
    response_model=ForgottenOut,
    tags=["users"],
    summary="Remove a person for good",
    responses=documented_errors(403, 404, 409, 422),
)
def forget_user(
    username: Username, body: ForgetIn, who: UserDep, lab: LabDep, request: Request
) -> ForgottenOut:
    """Remove a person and their name from every row; their runs kept under a pseudonym
    or deleted (lab administrators: a person may be in several courses; not while they
    hold or wait for a rig).
    """
    lab.authorize.require_lab(who, Action.ACCOUNT_FORGET)
    if username_form(username) == who.username:
        raise AccessDeniedError("you cannot remove yourself; ask another administrator")
    unknown = default_password_hasher().hash(secrets.token_urlsafe(32))
    written = lab.audit.forgotten(who.username, address=client_address(request), runs=body.runs)
    pseudonym = forget_person(lab.db, username, body.runs, unknown, audit=written)
    lab.names.forget()
    return ForgottenOut(pseudonym=pseudonym)
