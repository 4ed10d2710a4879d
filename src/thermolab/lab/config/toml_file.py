"""Reading a lab's TOML configuration file: every key checked, every error named.

The file's shape is a set of pydantic v2 models (``extra="forbid"``: an
unknown key is an error). They declare no defaults of their own: a key left
out inherits, from ``[rig_defaults]`` for a rig's limits, else from the
configuration's dataclasses (:mod:`.model`), where each default is declared
once. An error names the file, the key path, what was wrong and what is
allowed (:class:`~thermolab.errors.ConfigError`), in one line.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator
from pydantic_core import ErrorDetails

from thermolab.errors import ConfigError
from thermolab.lab.config.model import (
    DEFAULT_RIG,
    RIG_ID,
    AccessPolicy,
    CooldownPolicy,
    LabConfig,
    RigConfig,
    describe_value,
)
from thermolab.lab.config.retention import MAX_MONTHS, RetentionPolicy
from thermolab.lab.config.rig_kinds import parse_rig_spec
from thermolab.lab.config.smtp import SmtpConfig
from thermolab.lab.config.teacher_settings import check_caps

__all__ = ["load_config"]


def load_config(path: str | os.PathLike[str], data_dir: Path) -> LabConfig:
    """Read and check a TOML configuration file.

    Parameters
    ----------
    path : path-like
        The file.
    data_dir : Path
        The data folder (from the command line; the file does not set it).

    Returns
    -------
    LabConfig

    Raises
    ------
    ConfigError
        If the file is missing, is not valid TOML, or has an unknown key or a
        bad value; the message names the file and the key.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     file = Path(tmp, "lab.toml")
    ...     _ = file.write_text('[[rigs]]\\nid = "a"\\ntitle = "A"\\nspec = "sim"\\n'
    ...                         'control_time_limit = 600\\n')
    ...     load_config(file, Path(tmp)).rigs[0].control_time_limit
    600.0
    """
    file = Path(path)
    try:
        raw = tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{file}: no such configuration file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{file}: cannot read it ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{file}: not valid TOML ({exc})") from None
    try:
        parsed = _File.model_validate(raw)
    except ValidationError as exc:
        raise ConfigError(f"{file}: {_describe(exc.errors()[0])}") from None
    try:
        return parsed.build(data_dir)
    except ConfigError as exc:
        raise ConfigError(f"{file}: {exc}") from None


# -- the file's shape -------------------------------------------------------------------

# Numbers: TOML integers or floats (never strings or booleans), finite.
_Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
_Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
_NonNegative = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]
_Count = Annotated[int, Field(strict=True, ge=1)]
_Text = Annotated[str, Field(strict=True, min_length=1)]


def _one_word(value: str) -> str:
    # An address or a CSP source: a space, ';' or ',' would split the header it goes into.
    if not value.strip() or any(c in value for c in " \t\n;,"):
        raise ValueError(f"expected one word without spaces, ';' or ',', got {value!r}")
    return value.strip()


_Token = Annotated[str, Field(strict=True), AfterValidator(_one_word)]


class _Table(BaseModel):
    """A TOML table: unknown keys are errors; a key left out is ``None`` (inherited)."""

    model_config = ConfigDict(extra="forbid", frozen=True, str_strip_whitespace=True)

    def given(self) -> dict[str, Any]:
        """The keys the file sets (to apply over the inherited values)."""
        return {k: getattr(self, k) for k in self.model_fields_set}


class _Cooldown(_Table):
    mode: Literal["none", "ambient"] | None = None
    tolerance: _Positive | None = None
    max_seconds: _Positive | None = None
    input: _Number | None = None
    ambient: _Number | None = None

    def over(self, base: CooldownPolicy) -> CooldownPolicy:
        return replace(base, **self.given())


@dataclass(frozen=True, slots=True)
class _Limits:
    """A rig's limits as inherited: RigConfig's defaults, then ``[rig_defaults]``."""

    control_time_limit: float = DEFAULT_RIG.control_time_limit
    idle_limit: float | None = DEFAULT_RIG.idle_limit
    power_off_grace: float = DEFAULT_RIG.power_off_grace
    max_run_seconds: float = DEFAULT_RIG.max_run_seconds
    cooldown: CooldownPolicy = DEFAULT_RIG.cooldown
    caps: tuple[tuple[str, float], ...] = DEFAULT_RIG.caps
    twin_speedup: float = DEFAULT_RIG.twin_speedup  # the file's top-level ``speedup``


class _LimitsTable(_Table):
    control_time_limit: _Positive | None = None
    idle_limit: _NonNegative | None = None  # 0: never
    power_off_grace: _NonNegative | None = None
    max_run_seconds: _Positive | None = None
    cooldown: _Cooldown | None = None
    # The technician's bounds on teacher settings: name -> largest value a teacher may set.
    caps: dict[str, _Number] | None = None

    def over(self, base: _Limits) -> _Limits:
        given = {k: v for k, v in self.given().items() if k in _Limits.__dataclass_fields__}
        if "idle_limit" in given:
            given["idle_limit"] = given["idle_limit"] or None
        if self.cooldown is not None:
            given["cooldown"] = self.cooldown.over(base.cooldown)
        if self.caps is not None:
            # A rig's caps add to (and override) the defaults' caps.
            caps = {**dict(base.caps), **check_caps(self.caps, "caps")}
            given["caps"] = tuple(sorted(caps.items()))
        return replace(base, **given)


class _Rig(_LimitsTable):
    id: _Text
    title: _Text | None = None
    spec: _Text
    input_range: tuple[_Number, _Number] | None = None
    camera: _Text | None = None
    agent: Annotated[bool, Field(strict=True)] = False

    @field_validator("id")
    @classmethod
    def _id(cls, value: str) -> str:
        if not RIG_ID.match(value):
            raise ValueError(
                f"{value!r} is not a valid rig id (lower-case letters, digits, '-' and '_', at "
                "most 64 characters, starting with a letter or digit)"
            )
        return value

    @field_validator("spec")
    @classmethod
    def _spec(cls, value: str) -> str:
        parse_rig_spec(value)  # a ConfigError is a ValueError: pydantic names the key
        return value

    @field_validator("input_range")
    @classmethod
    def _range(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and not value[0] < value[1]:
            raise ValueError(f"min must be below max, got [{value[0]:g}, {value[1]:g}]")
        return value

    def build(self, limits: _Limits) -> RigConfig:
        rig = RigConfig(
            id=self.id,
            title=self.title or self.id,
            spec=self.spec,
            input_range=self.input_range,
            camera=self.camera,
            agent=self.agent,
        )
        return _with_limits(rig, self.over(limits))


class _Access(_Table):
    client_timeout: _Positive | None = None
    session_lifetime: _Positive | None = None
    session_idle_timeout: _Positive | None = None
    login_failures_per_user: _Count | None = None
    login_attempts_per_address: _Count | None = None
    login_window: _Positive | None = None
    cookie_samesite: Literal["strict", "lax"] | None = None
    cookie_secure: Literal["auto", "always", "never"] | None = None
    max_body_bytes: Annotated[int, Field(strict=True, ge=1024)] | None = None
    trusted_proxies: tuple[_Token, ...] | None = None
    frame_ancestors: tuple[_Token, ...] | None = None
    live_sockets_per_login: _Count | None = None
    live_sockets_per_rig: _Count | None = None
    live_replay_samples: Annotated[int, Field(strict=True, ge=2)] | None = None


class _Retention(_Table):
    months: Annotated[int, Field(strict=True, ge=1, le=MAX_MONTHS)] | None = None
    action: Literal["pseudonymise", "delete"] | None = None


class _Smtp(_Table):
    host: _Text
    port: Annotated[int, Field(strict=True, ge=1, le=65535)] | None = None
    sender: _Text | None = None
    starttls: Annotated[bool, Field(strict=True)] | None = None
    username: _Text | None = None
    password_env: _Token | None = None


class _File(_Table):
    title: _Text | None = None
    time_zone: _Text | None = None
    database_url: _Text | None = None
    speedup: _Positive | None = None
    access: _Access | None = None
    retention: _Retention | None = None
    smtp: _Smtp | None = None
    rig_defaults: _LimitsTable | None = None
    rigs: Annotated[list[_Rig], Field(min_length=1)] | None = None

    def build(self, data_dir: Path) -> LabConfig:
        first = _Limits() if self.speedup is None else _Limits(twin_speedup=self.speedup)
        limits = first if self.rig_defaults is None else self.rig_defaults.over(first)
        if self.rigs is None:
            # No rig declared: the default twin, with the file's rig defaults.
            rigs: tuple[RigConfig, ...] = (_with_limits(DEFAULT_RIG, limits),)
        else:
            rigs = tuple(rig.build(limits) for rig in self.rigs)
        access = (
            AccessPolicy()
            if self.access is None
            else replace(AccessPolicy(), **self.access.given())
        )
        top = self.given()
        return LabConfig(
            data_dir=data_dir,
            rigs=rigs,
            access=access,
            database_url=self.database_url,
            retention=RetentionPolicy(**(self.retention or _Retention()).given()),
            smtp=None if self.smtp is None else SmtpConfig(**self.smtp.given()),
            **{k: top[k] for k in ("title", "time_zone") if k in top},
        )


def _with_limits(rig: RigConfig, limits: _Limits) -> RigConfig:
    return replace(
        rig,
        control_time_limit=limits.control_time_limit,
        idle_limit=limits.idle_limit,
        power_off_grace=limits.power_off_grace,
        max_run_seconds=limits.max_run_seconds,
        cooldown=limits.cooldown,
        caps=limits.caps,
        twin_speedup=limits.twin_speedup,
    )


# -- errors in one line, with the key path --------------------------------------------------


def _key_path(loc: tuple[int | str, ...]) -> str:
    path = ""
    for part in loc:
        path += f"[{part}]" if isinstance(part, int) else (f".{part}" if path else str(part))
    return path


def _table_at(loc: tuple[int | str, ...]) -> type[_Table]:
    """The model of the table at ``loc`` (to list the keys allowed there)."""
    model: type[_Table] = _File
    nested: dict[str, type[_Table]] = {
        "access": _Access,
        "retention": _Retention,
        "smtp": _Smtp,
        "rig_defaults": _LimitsTable,
        "rigs": _Rig,
        "cooldown": _Cooldown,
    }
    for part in loc:
        if isinstance(part, str) and part in nested:
            model = nested[part]
    return model


def _describe(error: ErrorDetails) -> str:
    """One pydantic error as ``key.path: what was wrong (what is allowed)``."""
    loc = tuple(error["loc"])
    kind, ctx, value = error["type"], error.get("ctx", {}), error.get("input")
    key = _key_path(loc) or "the file"
    if kind == "extra_forbidden":
        allowed = ", ".join(_table_at(loc[:-1]).model_fields)
        return f"{key}: unknown key (allowed here: {allowed})"
    if "input_range" in loc and kind in ("missing", "too_long", "too_short", "tuple_type"):
        # A range of the wrong length: name the range, not its missing or extra entry.
        whole = loc[: loc.index("input_range") + 1]
        return f"{_key_path(whole)}: expected [min, max]"
    if kind == "missing":
        return f"{key}: required"
    if kind in ("greater_than", "greater_than_equal"):
        bound = f"> {ctx['gt']:g}" if kind == "greater_than" else f">= {ctx['ge']:g}"
        noun = "finite number"
        return f"{key}: expected a {noun} {bound}, got {value!r}"
    if kind == "less_than_equal":
        return f"{key}: expected at most {ctx['le']}, got {value!r}"
    if kind in ("float_type", "float_parsing", "int_type", "int_parsing", "int_from_float"):
        what = "a whole number" if kind.startswith("int") else "a number"
        return f"{key}: expected {what}, got {describe_value(value)}"
    if kind == "finite_number":
        return f"{key}: expected a finite number, got {value!r}"
    if kind == "literal_error":
        return f"{key}: expected one of {ctx['expected'].replace(' or ', ', ')}, got {value!r}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"{key}: expected a table, got {describe_value(value)}"
    if kind in ("list_type", "tuple_type", "too_short", "too_long") and loc[-1:] == ("rigs",):
        return f"{key}: expected one or more [[rigs]] tables, got {value!r}"
    if kind in ("list_type", "tuple_type", "too_short", "too_long"):
        return f"{key}: expected [min, max], got {value!r}"
    if kind in ("string_type", "string_too_short"):
        return f"{key}: expected a non-empty string, got {value!r}"
    message = str(error["msg"]).removeprefix("Value error, ")
    return f"{key}: {message}"
