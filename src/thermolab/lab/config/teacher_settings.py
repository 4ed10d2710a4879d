"""Teacher settings: the rig limits a teacher changes from the browser, each declared once.

A :class:`TeacherSetting` names one value of :class:`~thermolab.lab.config.RigConfig`
(``path``, dotted for the cool-down's), with its type, unit, range, help and when a
change takes effect. Everything else derives from :data:`TEACHER_SETTINGS`: the
first values (:func:`seed_values`, from the technician's TOML file), the range a
teacher may use on a rig (:func:`allowed_range`: the declared one, lowered by the
file's ``caps``; the cool-down input's is the rig's input range), the check of a
new value (:func:`check_value`), the effective rig (:func:`with_values`), the API's
schema and the browser's form (``GET /api/rigs/{rig}/settings`` lists them).

Adding a setting is one entry here (and its field in ``RigConfig``). A
setting may hold for some rigs only (``twins_only``: the twin speed-up, for the
twins the lab runs itself); :func:`settings_of` lists a rig's.

Examples
--------
>>> from thermolab.lab.config.model import DEFAULT_RIG
>>> seed_values(DEFAULT_RIG)["control_time_limit"]
300.0
>>> allowed_range(SETTINGS["max_run_seconds"], {"max_run_seconds": 7200.0}, None)
(10.0, 7200.0)
>>> check_value(SETTINGS["control_time_limit"], 5, (10.0, 86400.0))
Traceback (most recent call last):
...
thermolab.errors.SettingRangeError: control_time_limit = 5 s is out of range; allowed: 10 to 86400 s
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

from thermolab.errors import ConfigError, SettingRangeError
from thermolab.lab.config.model import DEFAULT_RIG, RigConfig

__all__ = [
    "COURSE_SETTINGS",
    "SETTINGS",
    "TEACHER_SETTINGS",
    "SettingValue",
    "TeacherSetting",
    "allowed_range",
    "check_caps",
    "check_value",
    "course_override",
    "seed_values",
    "settings_of",
    "value_of",
    "with_values",
]

SettingValue = float | str | None
"""A setting's value: a number, a choice, or ``None`` where the setting allows it."""

_DAY = 86400.0


@dataclass(frozen=True, slots=True)
class TeacherSetting:
    """One teacher setting of a rig.

    Attributes
    ----------
    name : str
        Its name in the API and the catalogues (``settings.<name>.label``).
    path : str
        The :class:`RigConfig` attribute it sets (``"cooldown.tolerance"``).
    type : {"number", "choice"}
    unit : {"s", "input", "output", ""}
        Seconds, or the rig's input or output unit (the rig says which).
    minimum, maximum : float or None
        Declared range (numbers); a technician's cap may lower ``maximum``.
        ``None`` for the cool-down input, whose range is the rig's input range.
    help : str
        One line, in English (the browser shows its catalogue's).
    applies : {"next_turn", "next_run", "now"}
        When a change takes effect: the turn going keeps its deadline and the
        run going its length; ``"now"`` is read at every check.
    choices : tuple of str
        For a choice.
    nullable : bool
        ``None`` is allowed (idle limit: never; cool-down input: the rig's safe input).
    per_course : bool
        A course may override it during its booked slots (:data:`COURSE_SETTINGS`).
    twins_only : bool
        Only the digital twins the lab runs itself have it (not hardware, nor a
        rig on a host: :attr:`RigConfig.lab_twin`).
    """

    name: str
    path: str
    type: Literal["number", "choice"]
    unit: Literal["s", "input", "output", ""]
    minimum: float | None
    maximum: float | None
    help: str
    applies: Literal["next_turn", "next_run", "now"]
    choices: tuple[str, ...] = ()
    nullable: bool = False
    per_course: bool = False
    twins_only: bool = False

    @property
    def default(self) -> SettingValue:
        """The lab's default (the default rig's value)."""
        return value_of(DEFAULT_RIG, self)

    def to_dict(self) -> dict[str, object]:
        """The declaration as the API publishes it (camelCase keys)."""
        return {
            "name": self.name,
            "type": self.type,
            "unit": self.unit,
            "minimum": self.minimum,
            "maximum": self.maximum,
            "default": self.default,
            "help": self.help,
            "applies": self.applies,
            "choices": list(self.choices),
            "nullable": self.nullable,
        }


TEACHER_SETTINGS: tuple[TeacherSetting, ...] = (
    TeacherSetting(
        "control_time_limit",
        "control_time_limit",
        "number",
        "s",
        10.0,
        _DAY,
        "Seconds of control in one turn (a run going when they run out is not cut).",
        "next_turn",
        per_course=True,
    ),
    TeacherSetting(
        "idle_limit",
        "idle_limit",
        "number",
        "s",
        10.0,
        _DAY,
        "Seconds without a command after which the turn ends; empty: never.",
        "now",
        nullable=True,
        per_course=True,
    ),
    TeacherSetting(
        "max_run_seconds",
        "max_run_seconds",
        "number",
        "s",
        10.0,
        _DAY,
        "Longest run START accepts, in seconds of real time.",
        "next_run",
        per_course=True,
    ),
    TeacherSetting(
        "cooldown_mode",
        "cooldown.mode",
        "choice",
        "",
        None,
        None,
        "Whether the rig cools back to ambient before the next turn starts.",
        "now",
        choices=("none", "ambient"),
    ),
    TeacherSetting(
        "cooldown_tolerance",
        "cooldown.tolerance",
        "number",
        "output",
        0.001,
        1000.0,
        "How close to ambient counts as cold, in the rig's output unit.",
        "now",
    ),
    TeacherSetting(
        "cooldown_max_seconds",
        "cooldown.max_seconds",
        "number",
        "s",
        0.0,
        _DAY,
        "Longest cool-down; after it the next turn starts anyway.",
        "now",
    ),
    TeacherSetting(
        "cooldown_input",
        "cooldown.input",
        "number",
        "input",
        None,
        None,
        "Input held while cooling (a fan: negative volts); empty: the rig's safe input.",
        "now",
        nullable=True,
    ),
    TeacherSetting(
        "twin_speedup",
        "twin_speedup",
        "number",
        "",
        1.0,
        1000.0,
        "How many times faster than real time the twin runs (1: real time); a run keeps "
        "the pace it started with.",
        "next_run",
        twins_only=True,
    ),
)

#: The settings by name.
SETTINGS: Mapping[str, TeacherSetting] = {s.name: s for s in TEACHER_SETTINGS}

#: The settings a course may override during its booked slots (the limits of a turn and a run).
COURSE_SETTINGS: tuple[TeacherSetting, ...] = tuple(s for s in TEACHER_SETTINGS if s.per_course)


def course_override(course_value: SettingValue, cap: float | None) -> SettingValue:
    """The value in force on a rig during a course's slot: the course's, lowered by the rig's cap.

    >>> course_override(900.0, 600.0), course_override(None, 600.0)
    (600.0, None)
    """
    if isinstance(course_value, float) and cap is not None:
        return min(course_value, cap)
    return course_value


def value_of(rig: RigConfig, setting: TeacherSetting) -> SettingValue:
    """The value ``rig`` has for ``setting``."""
    holder: object = rig
    for part in setting.path.split("."):
        holder = getattr(holder, part)
    if holder is None or isinstance(holder, str):
        return holder
    assert isinstance(holder, int | float)
    return float(holder)


def settings_of(rig: RigConfig) -> tuple[TeacherSetting, ...]:
    """The settings ``rig`` has, in declaration order (a ``twins_only`` one: a lab's twin).

    >>> from thermolab.lab.config.model import RigConfig
    >>> "twin_speedup" in [s.name for s in settings_of(RigConfig("k", "K", "tclab"))]
    False
    """
    return tuple(s for s in TEACHER_SETTINGS if rig.lab_twin or not s.twins_only)


def seed_values(rig: RigConfig) -> dict[str, SettingValue]:
    """Every setting's value in ``rig`` (the technician's file: the first values)."""
    return {s.name: value_of(rig, s) for s in settings_of(rig)}


def with_values(rig: RigConfig, values: Mapping[str, SettingValue]) -> RigConfig:
    """``rig`` with the given settings' values (names not declared are ignored)."""
    top: dict[str, object] = {}
    cooldown: dict[str, object] = {}
    for name, value in values.items():
        setting = SETTINGS.get(name)
        if setting is None:
            continue
        head, _, rest = setting.path.partition(".")
        if rest:
            cooldown[rest] = value
        else:
            top[head] = value
    if cooldown:
        top["cooldown"] = replace(rig.cooldown, **cooldown)  # type: ignore[arg-type]
    return replace(rig, **top)  # type: ignore[arg-type]


def allowed_range(
    setting: TeacherSetting,
    caps: Mapping[str, float],
    input_range: tuple[float, float] | None,
) -> tuple[float, float] | None:
    """The range a teacher may give ``setting`` on a rig (``None`` for a choice).

    The declared range, its maximum lowered by the technician's cap; the
    cool-down input's range is the rig's input range (``input_range``).
    """
    if setting.type != "number":
        return None
    if setting.minimum is None or setting.maximum is None:
        return input_range if input_range is not None else (-math.inf, math.inf)
    return (setting.minimum, min(setting.maximum, caps.get(setting.name, math.inf)))


def _unit(setting: TeacherSetting) -> str:
    return " s" if setting.unit == "s" else ""


def check_value(
    setting: TeacherSetting, value: object, bounds: tuple[float, float] | None
) -> SettingValue:
    """``value`` for ``setting``, checked against its type and ``bounds``.

    Raises
    ------
    SettingRangeError
        Naming the setting, the value and what is allowed.
    """
    lo, hi = bounds if bounds is not None else (math.nan, math.nan)
    if value is None and setting.nullable:
        return None
    if setting.type == "choice":
        if isinstance(value, str) and value in setting.choices:
            return value
        allowed = ", ".join(setting.choices)
        raise SettingRangeError(
            setting.name, f"{setting.name} = {value!r} is not allowed; one of: {allowed}", lo, hi
        )
    unit = _unit(setting)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SettingRangeError(
            setting.name, f"{setting.name}: expected a number, got {value!r}", lo, hi
        )
    number = float(value)
    if not (math.isfinite(number) and lo <= number <= hi):
        raise SettingRangeError(
            setting.name,
            f"{setting.name} = {value!r}{unit} is out of range; allowed: {lo:g} to {hi:g}{unit}",
            lo,
            hi,
        )
    return number


def check_caps(caps: Mapping[str, float], where: str) -> dict[str, float]:
    """A technician's caps: each names a number setting and lies within its declared range.

    Raises
    ------
    ConfigError
        Naming the key (``where``) and what is allowed.
    """
    capped = {s.name: s for s in TEACHER_SETTINGS if s.type == "number" and s.maximum is not None}
    out: dict[str, float] = {}
    for name, cap in caps.items():
        setting = capped.get(name)
        if setting is None:
            allowed = ", ".join(capped)
            raise ConfigError(f"{where}.{name}: not a setting with a cap (allowed: {allowed})")
        assert setting.minimum is not None
        assert setting.maximum is not None
        if not setting.minimum <= cap <= setting.maximum:
            raise ConfigError(
                f"{where}.{name}: expected a number from {setting.minimum:g} to "
                f"{setting.maximum:g}, got {cap!r}"
            )
        out[name] = float(cap)
    return out
