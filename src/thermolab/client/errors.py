"""What the client raises when the lab says no: one class with the lab's status, code and reason."""

from __future__ import annotations

from thermolab.errors import ThermoLabError

__all__ = ["LabRequestError", "TurnEndedError"]


class LabRequestError(ThermoLabError, RuntimeError):
    """The lab refused a request (4xx/5xx), or could not be reached.

    Attributes
    ----------
    status : int or None
        The HTTP status (``None``: no answer).
    code : str
        The lab's stable error code (``access_denied``, ``not_authenticated``,
        ``invalid_request``...) or ``unreachable``.
    detail : str
        The lab's reason, one line.
    """

    def __init__(
        self,
        method: str,
        path: str,
        status: int | None,
        code: str,
        detail: str,
        *,
        url: str | None = None,
    ):
        where = f"{method} {path}"
        if code == "unreachable":
            # No answer at all: nothing was refused, and the address is what to check.
            super().__init__(f"cannot reach the lab at {url or '?'} ({where}): {detail}")
        else:
            shown = f"{status} {code}" if status is not None else code
            super().__init__(f"the lab refused {where}: {detail} ({shown})")
        self.status = status
        self.code = code
        self.detail = detail


class TurnEndedError(ThermoLabError, RuntimeError):
    """This script's turn at a rig ended while it ran (time limit, a teacher, a revoked token...).

    Attributes
    ----------
    rig : str
        The rig.
    reason : str
        Why, as the lab said it.
    """

    def __init__(self, rig: str, reason: str):
        super().__init__(
            f"the turn at rig {rig!r} ended: {reason}. The lab put the rig at its safe input; "
            "ask for control again (a new TCLab() or Lab.control) to go on"
        )
        self.rig = rig
        self.reason = reason
