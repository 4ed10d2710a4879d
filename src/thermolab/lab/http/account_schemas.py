"""JSON bodies of logins and accounts: credentials, the session, users, passwords.

Password lengths are the accounts' own limits
(:mod:`thermolab.lab.accounts.security`), published in the schema.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from pydantic import Field

from thermolab.lab.accounts.security import MAX_PASSWORD_LENGTH, MIN_PASSWORD_LENGTH
from thermolab.lab.accounts.users import Principal, UserInfo
from thermolab.lab.http.bodies import In as _In
from thermolab.lab.http.bodies import Out as _Out

__all__ = ["CredentialsIn", "NewUserIn", "PasswordIn", "SessionOut", "UserOut"]


class CredentialsIn(_In):
    """Login: user name and password."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    password: Annotated[str, Field(min_length=1, max_length=1024)]


class SessionOut(_Out):
    """Who is logged in."""

    username: str
    display_name: str | None = Field(default=None, description="the name the user is shown by")
    role: Literal["student", "teacher"]
    expires_at: datetime | None
    must_change_password: bool = False
    admin: bool = Field(default=False, description="a lab administrator (accounts, rigs, LTI)")

    @classmethod
    def of(cls, who: Principal, display_name: str | None = None) -> SessionOut:
        """Build from a principal (and the display name, when known)."""
        return cls(
            username=who.username,
            display_name=display_name,
            role=who.role.value,
            expires_at=who.expires_at,
            must_change_password=who.must_change_password,
            admin=who.is_admin,
        )


class UserOut(_Out):
    """An account: its login name (normal form) and the name it is shown by."""

    username: str
    display_name: str | None
    role: Literal["student", "teacher"]
    created_at: datetime
    admin: bool = Field(default=False, description="a lab administrator (accounts, rigs, LTI)")

    @classmethod
    def of(cls, user: UserInfo) -> UserOut:
        """Build from a user record."""
        return cls(
            username=user.username,
            display_name=user.display_name,
            role=user.role.value,
            created_at=user.created_at,
            admin=user.admin,
        )


class NewUserIn(_In):
    """A new account (teachers only): the login name is normalised, the display name kept."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    display_name: Annotated[str | None, Field(max_length=256)] = None
    password: Annotated[str, Field(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)]
    role: Literal["student", "teacher"]
    admin: bool = Field(default=False, description="make this teacher a lab administrator")


class PasswordIn(_In):
    """A new password, with the acting user's current password (re-authentication)."""

    password: Annotated[str, Field(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)]
    current_password: Annotated[
        str | None,
        Field(
            max_length=MAX_PASSWORD_LENGTH,
            description="the password of the user making the change (required, also for "
            "a teacher changing someone else's)",
        ),
    ] = None
