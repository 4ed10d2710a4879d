"""Reading a lab's TOML configuration file: every key checked, every error named.

An error names the file, the key, what was wrong and what is allowed
(:class:`~thermolab.errors.ConfigError`).
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, cast

from thermolab.errors import ConfigError
from thermolab.lab.config.model import (
    RIG_ID,
    AccessPolicy,
    CooldownPolicy,
    LabConfig,
    RigConfig,
    check_number,
    describe_value,
)
from thermolab.lab.config.rig_kinds import parse_rig_spec

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
        return _build_config(raw, data_dir)
    except ConfigError as exc:
        raise ConfigError(f"{file}: {exc}") from None


# -- validation -------------------------------------------------------------------------


class _Table:
    """A TOML table being read: typed getters that name the key, and a check for leftovers."""

    def __init__(self, raw: object, path: str, allowed: tuple[str, ...]) -> None:
        if not isinstance(raw, Mapping):
            raise ConfigError(f"{path or 'the file'}: expected a table, got {describe_value(raw)}")
        self._raw: Mapping[str, Any] = raw
        self._path = path
        unknown = sorted(set(raw) - set(allowed))
        if unknown:
            raise ConfigError(
                f"{self.key(unknown[0])}: unknown key (allowed here: {', '.join(allowed)})"
            )

    def key(self, name: str) -> str:
        return f"{self._path}.{name}" if self._path else name

    def has(self, name: str) -> bool:
        return name in self._raw

    def get(self, name: str) -> object:
        return self._raw.get(name)

    def string(self, name: str, default: str | None = None) -> str:
        value = self.get(name)
        if value is None:
            if default is None:
                raise ConfigError(f"{self.key(name)}: required (a string)")
            return default
        if not isinstance(value, str) or not value.strip():
            raise ConfigError(f"{self.key(name)}: expected a non-empty string, got {value!r}")
        return value.strip()

    def number(
        self, name: str, default: float, *, minimum: float = 0.0, strict: bool = True
    ) -> float:
        value = self.get(name)
        if value is None:
            return default
        return check_number(value, self.key(name), minimum=minimum, strict=strict)

    def integer(self, name: str, default: int, *, minimum: int = 1) -> int:
        value = self.get(name)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise ConfigError(
                f"{self.key(name)}: expected a whole number >= {minimum}, got {value!r}"
            )
        return value

    def strings(self, name: str, default: tuple[str, ...]) -> tuple[str, ...]:
        value = self.get(name)
        if value is None:
            return default
        if not isinstance(value, list) or not all(
            isinstance(v, str) and v.strip() and not any(c in v for c in " ;,\n") for v in value
        ):
            raise ConfigError(
                f"{self.key(name)}: expected a list of strings without spaces, ';' or ',', "
                f"got {value!r}"
            )
        return tuple(v.strip() for v in value)

    def choice(self, name: str, default: str, allowed: tuple[str, ...]) -> str:
        value = self.get(name)
        if value is None:
            return default
        if value not in allowed:
            options = ", ".join(repr(a) for a in allowed)
            raise ConfigError(f"{self.key(name)}: expected one of {options}, got {value!r}")
        return str(value)


_LIMIT_KEYS = ("control_time_limit", "idle_limit", "power_off_grace", "cooldown")
_ACCESS_KEYS = tuple(AccessPolicy.__dataclass_fields__)
_COOLDOWN_KEYS = tuple(CooldownPolicy.__dataclass_fields__)
_RIG_KEYS = ("id", "title", "spec", "input_range", "camera", *_LIMIT_KEYS)
_TOP_KEYS = ("title", "database_url", "speedup", "access", "rig_defaults", "rigs")


@dataclass(frozen=True, slots=True)
class _RigDefaults:
    control_time_limit: float = 300.0
    idle_limit: float | None = 120.0
    power_off_grace: float = 60.0
    cooldown: CooldownPolicy = field(default_factory=CooldownPolicy)


def _read_limits(table: _Table, base: _RigDefaults) -> _RigDefaults:
    idle = base.idle_limit
    if table.has("idle_limit"):
        value = table.number("idle_limit", 0.0, minimum=0.0, strict=False)
        idle = value if value > 0 else None
    cooldown = base.cooldown
    if table.has("cooldown"):
        cooldown = _read_cooldown(table.get("cooldown"), table.key("cooldown"), base.cooldown)
    return _RigDefaults(
        control_time_limit=table.number("control_time_limit", base.control_time_limit),
        idle_limit=idle,
        power_off_grace=table.number(
            "power_off_grace", base.power_off_grace, minimum=0.0, strict=False
        ),
        cooldown=cooldown,
    )


def _read_cooldown(raw: object, path: str, base: CooldownPolicy) -> CooldownPolicy:
    table = _Table(raw, path, _COOLDOWN_KEYS)
    mode = table.choice("mode", base.mode, ("none", "ambient"))
    input_value = table.get("input")
    ambient = table.get("ambient")
    policy = CooldownPolicy(
        mode=cast(Literal["none", "ambient"], mode),
        tolerance=table.number("tolerance", base.tolerance),
        max_seconds=table.number("max_seconds", base.max_seconds),
        input=(
            base.input
            if input_value is None
            else check_number(input_value, table.key("input"), minimum=-math.inf, strict=False)
        ),
        ambient=(
            base.ambient
            if ambient is None
            else check_number(ambient, table.key("ambient"), minimum=-math.inf, strict=False)
        ),
    )
    return policy


def _read_range(raw: object, key: str) -> tuple[float, float]:
    if not isinstance(raw, list) or len(raw) != 2:
        raise ConfigError(f"{key}: expected [min, max], got {raw!r}")
    low = check_number(raw[0], f"{key}[0]", minimum=-math.inf, strict=False)
    high = check_number(raw[1], f"{key}[1]", minimum=-math.inf, strict=False)
    if not low < high:
        raise ConfigError(f"{key}: min must be below max, got [{low:g}, {high:g}]")
    return (low, high)


def _build_config(raw: Mapping[str, Any], data_dir: Path) -> LabConfig:
    top = _Table(raw, "", _TOP_KEYS)
    title = top.string("title", "ThermoLab")
    database_url = top.get("database_url")
    if database_url is not None and (not isinstance(database_url, str) or not database_url):
        raise ConfigError(f"database_url: expected a database URL string, got {database_url!r}")
    speedup = top.number("speedup", 1.0)

    access = AccessPolicy()
    if top.has("access"):
        table = _Table(top.get("access"), "access", _ACCESS_KEYS)
        access = AccessPolicy(
            client_timeout=table.number("client_timeout", access.client_timeout),
            session_lifetime=table.number("session_lifetime", access.session_lifetime),
            session_idle_timeout=table.number("session_idle_timeout", access.session_idle_timeout),
            login_failures_per_user=table.integer(
                "login_failures_per_user", access.login_failures_per_user
            ),
            login_attempts_per_address=table.integer(
                "login_attempts_per_address", access.login_attempts_per_address
            ),
            login_window=table.number("login_window", access.login_window),
            cookie_samesite=cast(
                Literal["strict", "lax"],
                table.choice("cookie_samesite", access.cookie_samesite, ("strict", "lax")),
            ),
            cookie_secure=cast(
                Literal["auto", "always", "never"],
                table.choice("cookie_secure", access.cookie_secure, ("auto", "always", "never")),
            ),
            max_body_bytes=table.integer("max_body_bytes", access.max_body_bytes, minimum=1024),
            trusted_proxies=table.strings("trusted_proxies", access.trusted_proxies),
            frame_ancestors=table.strings("frame_ancestors", access.frame_ancestors),
        )

    defaults = _RigDefaults()
    if top.has("rig_defaults"):
        table = _Table(top.get("rig_defaults"), "rig_defaults", _LIMIT_KEYS)
        defaults = _read_limits(table, defaults)

    raw_rigs = top.get("rigs")
    if raw_rigs is None:
        raise ConfigError("rigs: declare at least one rig with a [[rigs]] table")
    if not isinstance(raw_rigs, list) or not raw_rigs:
        raise ConfigError("rigs: expected one or more [[rigs]] tables")
    rigs = tuple(_read_rig(item, f"rigs[{i}]", defaults) for i, item in enumerate(raw_rigs))
    return LabConfig(
        data_dir=data_dir,
        rigs=rigs,
        access=access,
        database_url=database_url,
        speedup=speedup,
        title=title,
    )


def _read_rig(raw: object, path: str, defaults: _RigDefaults) -> RigConfig:
    table = _Table(raw, path, _RIG_KEYS)
    rig_id = table.string("id")
    if not RIG_ID.match(rig_id):
        raise ConfigError(
            f"{table.key('id')}: {rig_id!r} is not a valid rig id (lower-case letters, digits, "
            "'-' and '_', at most 64 characters, starting with a letter or digit)"
        )
    spec = table.string("spec")
    try:
        parse_rig_spec(spec)
    except ConfigError as exc:
        raise ConfigError(f"{table.key('spec')}: {exc}") from None
    input_range = None
    if table.has("input_range"):
        input_range = _read_range(table.get("input_range"), table.key("input_range"))
    limits = _read_limits(table, defaults)
    camera = table.get("camera")
    if camera is not None and (not isinstance(camera, str) or not camera.strip()):
        raise ConfigError(f"{table.key('camera')}: expected a URL or device path, got {camera!r}")
    rig = RigConfig(
        id=rig_id,
        title=table.string("title", rig_id),
        spec=spec,
        input_range=input_range,
        control_time_limit=limits.control_time_limit,
        idle_limit=limits.idle_limit,
        power_off_grace=limits.power_off_grace,
        cooldown=limits.cooldown,
        camera=camera,
    )
    return rig
