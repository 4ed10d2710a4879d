"""Teachers' rig settings refused (issue #10): out of range, not for this rig, changed meanwhile."""

from __future__ import annotations

from thermolab.errors.base import ConflictError, InvalidParameterError

__all__ = [
    "SettingNotForRigError",
    "SettingRangeError",
    "SettingsChangedError",
    "SpeedupRefusedError",
]


class SettingRangeError(InvalidParameterError):
    """A teacher setting outside its allowed range (the message names the range).

    ``setting`` is its name, ``minimum``/``maximum`` the range in force for the rig.
    """

    def __init__(self, setting: str, message: str, minimum: float, maximum: float) -> None:
        self.setting = setting
        self.minimum = minimum
        self.maximum = maximum
        super().__init__(message)


class SettingNotForRigError(InvalidParameterError):
    """A teacher setting this rig does not have (the twin speed-up of a hardware rig).

    ``setting`` is its name.
    """

    def __init__(self, setting: str, message: str) -> None:
        self.setting = setting
        super().__init__(message)


class SpeedupRefusedError(InvalidParameterError):
    """A speed-up a rig does not allow for a turn (the message names the rig and what it allows)."""


class SettingsChangedError(ConflictError):
    """Someone saved a rig's settings since the version the change was based on."""
