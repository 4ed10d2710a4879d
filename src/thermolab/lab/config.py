"""The lab's configuration: which rigs it serves, their limits, the access policy.

A lab runs with no configuration file at all (one digital twin, a SQLite
database in the data folder). A TOML file declares more::

    title = "Control lab, room 2.14"
    database_url = "postgresql+psycopg://lab@db.example/thermolab"   # optional
    speedup = 1.0            # twin rigs run this many times faster than real time

    [access]                 # lab-wide policy (every key optional)
    client_timeout = 15      # s without contact before a controller's client counts as gone
    session_lifetime = 43200 # s a login lasts at most
    session_idle_timeout = 7200
    login_failures_per_user = 5
    login_attempts_per_address = 30
    login_window = 60        # s over which the two limits above count
    cookie_samesite = "strict"   # or "lax"
    cookie_secure = "auto"       # "auto" (when the request is https), "always", "never"
    max_body_bytes = 65536

    [rig_defaults]           # limits every rig inherits unless it sets its own
    control_time_limit = 300 # s of control per turn
    idle_limit = 120         # s without a command before control ends (0: never)
    power_off_grace = 60     # s a free rig with an empty queue stays powered

    [[rigs]]
    id = "twin-1"
    title = "Digital twin of the paper's box"
    spec = "sim"             # sim, sim:PRESET (paper, paper-practical, tclab), tclab, tclab:PORT
    input_range = [0, 10]    # optional, narrows the rig's published range
    cooldown = { mode = "ambient", tolerance = 0.05, max_seconds = 900, input = -10 }

Every key is checked; an error names the key, what was wrong and what is
allowed (:class:`~thermolab.errors.ConfigError`).
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, cast

import platformdirs

from thermolab.errors import ConfigError, NotFoundError
from thermolab.rigs import PRESETS, RIG_SPECS

__all__ = [
    "AccessPolicy",
    "CooldownPolicy",
    "LabConfig",
    "RigConfig",
    "default_config",
    "default_database_url",
    "load_config",
    "parse_rig_spec",
    "resolve_data_dir",
]

_RIG_ID = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")
DATABASE_FILE = "thermolab.sqlite3"


@dataclass(frozen=True, slots=True)
class CooldownPolicy:
    """Whether a rig is cooled back to ambient before the next controller starts.

    Attributes
    ----------
    mode : {"none", "ambient"}
        ``"ambient"``: after a turn ends, the rig is held at ``input`` until its
        output is within ``tolerance`` of ambient (the step method needs a cold
        start), at most ``max_seconds``.
    tolerance : float
        How close to ambient counts as cold, in the rig's output unit.
    max_seconds : float
        Longest cool-down; after it the next controller starts anyway.
    input : float or None
        Input held during the cool-down (a fan: negative volts); ``None`` is
        the rig's safe input.
    ambient : float or None
        The ambient output; ``None`` takes the first reading after the lab
        powers the rig on from its safe state.

    Examples
    --------
    >>> CooldownPolicy().mode
    'none'
    """

    mode: Literal["none", "ambient"] = "none"
    tolerance: float = 0.5
    max_seconds: float = 1800.0
    input: float | None = None
    ambient: float | None = None

    @property
    def enabled(self) -> bool:
        """``True`` when the rig cools down between turns."""
        return self.mode == "ambient"


@dataclass(frozen=True, slots=True)
class AccessPolicy:
    """Lab-wide rules for sessions, logins and requests.

    Attributes
    ----------
    client_timeout : float
        Seconds without contact after which a controller (or a queued user)
        counts as gone.
    session_lifetime : float
        Seconds a login lasts at most.
    session_idle_timeout : float
        Seconds without any request after which a login expires.
    login_failures_per_user : int
        Failed logins per user name within ``login_window`` before 429.
    login_attempts_per_address : int
        Login attempts per client address within ``login_window`` before 429.
    login_window : float
        Seconds over which the two login limits count.
    cookie_samesite : {"strict", "lax"}
        SameSite attribute of the session cookie.
    cookie_secure : {"auto", "always", "never"}
        Secure attribute: ``"auto"`` sets it when the request came over https.
    max_body_bytes : int
        Largest request body accepted (413 beyond).

    Examples
    --------
    >>> AccessPolicy().client_timeout
    15.0
    """

    client_timeout: float = 15.0
    session_lifetime: float = 12 * 3600.0
    session_idle_timeout: float = 2 * 3600.0
    login_failures_per_user: int = 5
    login_attempts_per_address: int = 30
    login_window: float = 60.0
    cookie_samesite: Literal["strict", "lax"] = "strict"
    cookie_secure: Literal["auto", "always", "never"] = "auto"
    max_body_bytes: int = 64 * 1024


@dataclass(frozen=True, slots=True)
class RigConfig:
    """One rig the lab serves.

    Attributes
    ----------
    id : str
        Short name used in URLs (lower case letters, digits, ``-``, ``_``).
    title : str
        Human-readable name.
    spec : str
        What the rig is: ``sim`` (digital twin of the paper's box),
        ``sim:PRESET`` (another twin preset, e.g. ``sim:tclab``), ``tclab``
        (a TCLab kit, found automatically) or ``tclab:PORT`` (a kit on that port).
    input_range : tuple of float or None
        Narrows the rig's published input range; ``None`` keeps it.
    control_time_limit : float
        Seconds of control per turn.
    idle_limit : float or None
        Seconds without a command after which control ends; ``None``: never.
    power_off_grace : float
        Seconds a rig with no controller and an empty queue stays powered.
    cooldown : CooldownPolicy
        Cool-down between turns.
    camera : str or None
        Camera of a real rig (URL or device); ``None`` draws the twin's state.

    Examples
    --------
    >>> RigConfig("twin", "Digital twin", "sim").control_time_limit
    300.0
    """

    id: str
    title: str
    spec: str
    input_range: tuple[float, float] | None = None
    control_time_limit: float = 300.0
    idle_limit: float | None = 120.0
    power_off_grace: float = 60.0
    cooldown: CooldownPolicy = field(default_factory=CooldownPolicy)
    camera: str | None = None

    @property
    def kind(self) -> str:
        """``"sim"`` or ``"tclab"`` (the part of ``spec`` before the colon)."""
        return parse_rig_spec(self.spec)[0]


@dataclass(frozen=True, slots=True)
class LabConfig:
    """Everything ``thermolab serve`` needs to start a lab.

    Attributes
    ----------
    data_dir : Path
        Folder for the SQLite database and run records.
    rigs : tuple of RigConfig
        The rigs, in display order (ids unique).
    access : AccessPolicy
        Lab-wide rules.
    database_url : str or None
        SQLAlchemy URL; ``None`` is SQLite in ``data_dir``.
    speedup : float
        Twin rigs run this many times faster than real time.
    title : str
        Name of the lab shown to users.

    Examples
    --------
    >>> config = default_config(Path("/tmp/lab"))
    >>> [rig.id for rig in config.rigs], config.database
    (['twin'], 'sqlite:////tmp/lab/thermolab.sqlite3')
    """

    data_dir: Path
    rigs: tuple[RigConfig, ...]
    access: AccessPolicy = field(default_factory=AccessPolicy)
    database_url: str | None = None
    speedup: float = 1.0
    title: str = "ThermoLab"

    def __post_init__(self) -> None:
        ids = [rig.id for rig in self.rigs]
        if not ids:
            raise ConfigError("a lab needs at least one rig")
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ConfigError(f"rig ids must be unique; repeated: {', '.join(duplicates)}")

    @property
    def database(self) -> str:
        """The database URL in use (the SQLite default when none was given)."""
        return self.database_url or default_database_url(self.data_dir)

    def rig(self, rig_id: str) -> RigConfig:
        """Return the rig called ``rig_id``.

        Raises
        ------
        NotFoundError
            If there is no such rig (the message lists the rigs there are).
        """
        for rig in self.rigs:
            if rig.id == rig_id:
                return rig
        known = ", ".join(rig.id for rig in self.rigs)
        raise NotFoundError(f"no rig called {rig_id!r}; the lab has: {known}")

    def with_overrides(
        self, *, database_url: str | None = None, speedup: float | None = None
    ) -> LabConfig:
        """Return a copy with command-line overrides applied (``None`` keeps a value).

        Raises
        ------
        ConfigError
            If ``speedup`` is not a positive finite number.
        """
        if speedup is not None:
            _check_speedup(speedup, "--speedup")
        return replace(
            self,
            database_url=database_url if database_url is not None else self.database_url,
            speedup=speedup if speedup is not None else self.speedup,
        )


def resolve_data_dir(data_dir: str | os.PathLike[str] | None = None) -> Path:
    """Return the data folder: the argument, else ``$THERMOLAB_DATA_DIR``, else a per-user one.

    Parameters
    ----------
    data_dir : path-like, optional
        The ``--data-dir`` given on the command line.

    Returns
    -------
    Path
        An absolute path (not created here).

    Examples
    --------
    >>> resolve_data_dir("/srv/lab")
    PosixPath('/srv/lab')
    """
    if data_dir is not None:
        return Path(data_dir).expanduser().resolve()
    env = os.environ.get("THERMOLAB_DATA_DIR")
    if env:
        return Path(env).expanduser().resolve()
    return Path(platformdirs.user_data_dir("thermolab", appauthor=False)).resolve()


def default_database_url(data_dir: Path) -> str:
    """Return the SQLite URL of the database file in ``data_dir``.

    Examples
    --------
    >>> default_database_url(Path("/srv/lab"))
    'sqlite:////srv/lab/thermolab.sqlite3'
    """
    return f"sqlite:///{data_dir / DATABASE_FILE}"


def default_config(data_dir: Path) -> LabConfig:
    """Return the configuration of a lab started without a file: one digital twin.

    Examples
    --------
    >>> default_config(Path("/srv/lab")).rigs[0].spec
    'sim'
    """
    return LabConfig(
        data_dir=data_dir,
        rigs=(RigConfig("twin", "Digital twin of the paper's box", "sim"),),
    )


def parse_rig_spec(spec: str) -> tuple[str, str | None]:
    """Split a rig spec into its kind and argument, checking it names a known rig.

    Parameters
    ----------
    spec : str
        ``sim`` (the paper's twin), ``sim:PRESET`` (a twin preset of
        :data:`thermolab.rigs.PRESETS`), ``tclab`` (a kit, auto-detected) or
        ``tclab:PORT``.

    Returns
    -------
    tuple
        ``(kind, argument)``: ``("sim", None)``, ``("sim", "tclab")``,
        ``("tclab", "/dev/ttyUSB0")``.

    Raises
    ------
    ConfigError
        If the spec is not one of the forms above.

    Examples
    --------
    >>> parse_rig_spec("tclab:/dev/ttyUSB0")
    ('tclab', '/dev/ttyUSB0')
    >>> parse_rig_spec("sim")
    ('sim', None)
    """
    kind, sep, arg = spec.strip().partition(":")
    arg = arg.strip()
    if kind == "sim" and not sep:
        return ("sim", None)
    if kind == "sim" and arg in PRESETS:
        return ("sim", arg)
    if kind == "tclab" and not sep:
        return ("tclab", None)
    if kind == "tclab" and arg:
        return ("tclab", arg)
    raise ConfigError(f"rig spec {spec!r} is not understood; use one of: {', '.join(RIG_SPECS)}")


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
            raise ConfigError(f"{path or 'the file'}: expected a table, got {_describe(raw)}")
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
        return _number(value, self.key(name), minimum=minimum, strict=strict)

    def integer(self, name: str, default: int, *, minimum: int = 1) -> int:
        value = self.get(name)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise ConfigError(
                f"{self.key(name)}: expected a whole number >= {minimum}, got {value!r}"
            )
        return value

    def choice(self, name: str, default: str, allowed: tuple[str, ...]) -> str:
        value = self.get(name)
        if value is None:
            return default
        if value not in allowed:
            options = ", ".join(repr(a) for a in allowed)
            raise ConfigError(f"{self.key(name)}: expected one of {options}, got {value!r}")
        return str(value)


def _describe(value: object) -> str:
    return f"{type(value).__name__} {value!r}"


def _number(value: object, key: str, *, minimum: float = 0.0, strict: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{key}: expected a number, got {_describe(value)}")
    number = float(value)
    ok = math.isfinite(number) and (number > minimum if strict else number >= minimum)
    if not ok:
        bound = f"> {minimum:g}" if strict else f">= {minimum:g}"
        raise ConfigError(f"{key}: expected a finite number {bound}, got {value!r}")
    return number


def _check_speedup(value: float, key: str) -> float:
    return _number(value, key, minimum=0.0, strict=True)


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
            else _number(input_value, table.key("input"), minimum=-math.inf, strict=False)
        ),
        ambient=(
            base.ambient
            if ambient is None
            else _number(ambient, table.key("ambient"), minimum=-math.inf, strict=False)
        ),
    )
    return policy


def _read_range(raw: object, key: str) -> tuple[float, float]:
    if not isinstance(raw, list) or len(raw) != 2:
        raise ConfigError(f"{key}: expected [min, max], got {raw!r}")
    low = _number(raw[0], f"{key}[0]", minimum=-math.inf, strict=False)
    high = _number(raw[1], f"{key}[1]", minimum=-math.inf, strict=False)
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
    if not _RIG_ID.match(rig_id):
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
