"""What the client raises when the lab says no: one class with the lab's status, code and reason."""

from __future__ import annotations

from thermolab.errors import ThermoLabError

__all__ = ["LabRequestError"]


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

    def __init__(self, method: str, path: str, status: int | None, code: str, detail: str):
        where = f"{method} {path}"
        shown = f"{status} {code}" if status is not None else code
        super().__init__(f"the lab refused {where}: {detail} ({shown})")
        self.status = status
        self.code = code
        self.detail = detail
