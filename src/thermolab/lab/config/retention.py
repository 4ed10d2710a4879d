"""The retention setting: how long the lab keeps people of courses closed at the end of a term.

Unset (the default), nothing is ever removed automatically: an administrator
removes last term's students by hand (``thermolab course purge-students``).
Set, the people of courses closed for longer than ``months`` (and in no
open course) are removed daily, as ``action`` says
(:mod:`thermolab.lab.classes.retention` does it). The operator sets it in
three places, the later over the earlier: the configuration file's
``[retention]`` table, the environment (:data:`MONTHS_VARIABLE`,
:data:`ACTION_VARIABLE`), and ``thermolab serve --retention-months N
--retention-action ACTION``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal, cast, get_args

from thermolab.errors import ConfigError

__all__ = [
    "ACTION_VARIABLE",
    "MAX_MONTHS",
    "MONTHS_VARIABLE",
    "RetentionAction",
    "RetentionPolicy",
    "check_action",
    "check_months",
]

RetentionAction = Literal["pseudonymise", "delete"]
"""What becomes of a person past the retention period (their runs kept under a pseudonym, or
deleted with them)."""

MAX_MONTHS = 1200
"""The longest retention period a lab may set (a hundred years: longer is a typo)."""

MONTHS_VARIABLE = "THERMOLAB_RETENTION_MONTHS"
ACTION_VARIABLE = "THERMOLAB_RETENTION_ACTION"


@dataclass(frozen=True, slots=True)
class RetentionPolicy:
    """How long people of closed courses are kept, and what becomes of them then.

    Attributes
    ----------
    months : int or None
        Whole months after a person's last course closed; ``None``: never
        removed automatically.
    action : {"pseudonymise", "delete"}
        ``"pseudonymise"``: the account goes, its runs, turns and hand-ins stay
        under a pseudonym for the class's statistics; ``"delete"``: they go too.

    Examples
    --------
    >>> RetentionPolicy().enabled, RetentionPolicy(24).enabled
    (False, True)
    """

    months: int | None = None
    action: RetentionAction = "pseudonymise"

    @property
    def enabled(self) -> bool:
        """``True`` when the lab removes people automatically."""
        return self.months is not None

    def over(
        self, months: int | None = None, action: RetentionAction | None = None
    ) -> RetentionPolicy:
        """This policy with ``months`` and ``action`` applied (``None`` keeps a value)."""
        return replace(
            self,
            months=self.months if months is None else months,
            action=self.action if action is None else action,
        )

    def with_environment(self, environ: Mapping[str, str] = os.environ) -> RetentionPolicy:
        """This policy with :data:`MONTHS_VARIABLE` and :data:`ACTION_VARIABLE` applied.

        An empty variable counts as unset.

        Raises
        ------
        ConfigError
            A bad value (naming the variable).

        Examples
        --------
        >>> RetentionPolicy().with_environment({"THERMOLAB_RETENTION_MONTHS": "18"}).months
        18
        """
        months_text = environ.get(MONTHS_VARIABLE, "").strip()
        action_text = environ.get(ACTION_VARIABLE, "").strip()
        months = None
        if months_text:
            try:
                months = int(months_text)
            except ValueError:
                raise ConfigError(
                    f"{MONTHS_VARIABLE}: expected a whole number of months, got {months_text!r}"
                ) from None
            check_months(months, MONTHS_VARIABLE)
        action = check_action(action_text, ACTION_VARIABLE) if action_text else None
        return self.over(months, action)


def check_months(months: int, key: str) -> int:
    """``months`` if it is a retention period (1 to :data:`MAX_MONTHS`); else a ConfigError."""
    if isinstance(months, bool) or not isinstance(months, int) or not 1 <= months <= MAX_MONTHS:
        raise ConfigError(
            f"{key}: expected a whole number of months from 1 to {MAX_MONTHS}, got {months!r}"
        )
    return months


def check_action(action: str, key: str) -> RetentionAction:
    """``action`` if it is a :data:`RetentionAction`; else a ConfigError naming ``key``."""
    if action in get_args(RetentionAction):
        return cast(RetentionAction, action)
    raise ConfigError(f"{key}: expected pseudonymise or delete, got {action!r}")
