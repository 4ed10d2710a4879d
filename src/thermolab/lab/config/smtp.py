"""The ``[smtp]`` table: the mail server the lab sends booking reminders through.

No ``[smtp]`` table: no reminder is sent (the calendar page says so, and
nobody is asked for an address). The password is never in the file: it is
read from the environment variable ``password_env`` names, when the server
wants a login.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SmtpConfig"]


@dataclass(frozen=True, slots=True)
class SmtpConfig:
    """Where the lab's reminder e-mails go out.

    Attributes
    ----------
    host : str
    port : int
        25 by default (587 with ``starttls``, usually).
    sender : str
        The ``From`` address.
    starttls : bool
        Upgrade the connection with STARTTLS before sending.
    username : str or None
        Log in as this user (the password from ``password_env``).
    password_env : str or None
        The environment variable that holds the password.
    """

    host: str
    port: int = 25
    sender: str = "thermolab@localhost"
    starttls: bool = False
    username: str | None = None
    password_env: str | None = None
