"""The lab's configuration: which rigs it serves, their limits, the access policy.

A lab runs with no configuration file at all (one digital twin, a SQLite
database in the data folder). A TOML file declares more::

    title = "Control lab, room 2.14"
    database_url = "postgresql+psycopg://lab@db.example/thermolab"   # optional
    speedup = 1.0            # the twins' first speed-up (a teacher's setting: twin_speedup)

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
    trusted_proxies = []         # addresses whose X-Forwarded-For is believed (default: none)
    frame_ancestors = ["'self'"] # CSP frame-ancestors: who may embed the lab (e.g. an LMS)
    live_sockets_per_login = 4   # live WebSockets one login may hold at once (4429 beyond)
    live_sockets_per_rig = 500   # live WebSockets one rig may have at once (4503 beyond)
    live_replay_samples = 20000  # stored samples one socket may replay (the newest; see docs)

    [retention]              # optional: unset, nobody is removed automatically
    months = 24              # people whose last course closed this long ago are removed
    action = "pseudonymise"  # their runs kept under a pseudonym; or "delete"

    [rig_defaults]           # limits every rig inherits unless it sets its own
    control_time_limit = 300 # s of control per turn
    idle_limit = 120         # s without a command before control ends (0: never)
    power_off_grace = 60     # s a free rig with an empty queue stays powered
    max_run_seconds = 3600   # s of real time the longest run may last (a run covers the turn)

    [[rigs]]
    id = "twin-1"
    title = "Digital twin of the paper's box"
    spec = "sim"             # sim, sim:PRESET (paper, paper-practical, tclab, kit), tclab[:PORT]
    input_range = [0, 10]    # optional, narrows the rig's published range
    cooldown = { mode = "ambient", tolerance = 0.05, max_seconds = 900, input = -10 }

Without ``[[rigs]]`` the lab serves its one default twin, with the file's
``[rig_defaults]`` applied (a teacher changes one limit without declaring it).

Every key is checked; an error names the key, what was wrong and what is
allowed (:class:`~thermolab.errors.ConfigError`).
"""

from __future__ import annotations

import math
import os
import re
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import platformdirs

from thermolab.errors import ConfigError, NotFoundError
from thermolab.lab.config.retention import RetentionPolicy
from thermolab.lab.config.smtp import SmtpConfig
from thermolab.lab.config.time_zones import is_known_zone
from thermolab.rigs import RigSpec

__all__ = [
    "DATABASE_FILE",
    "DEFAULT_RIG",
    "QUICK_START_SPEEDUP",
    "RIG_ID",
    "AccessPolicy",
    "CooldownPolicy",
    "LabConfig",
    "RigConfig",
    "RigSettingsBoard",
    "check_number",
    "check_speedup",
    "default_config",
    "default_database_url",
    "describe_value",
    "resolve_data_dir",
]

RIG_ID = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")
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
        Failed logins of one (user name, address) before the doubling delays start.
    login_attempts_per_address : int
        Login attempts per client address within ``login_window`` before 429.
    login_window : float
        Seconds over which the address limit counts; also the longest login delay.
    cookie_samesite : {"strict", "lax"}
        SameSite attribute of the session cookie.
    cookie_secure : {"auto", "always", "never"}
        Secure attribute: ``"auto"`` sets it when the request came over https.
    max_body_bytes : int
        Largest request body accepted (413 beyond).
    trusted_proxies : tuple of str
        Addresses (or networks) of reverse proxies whose ``X-Forwarded-For``
        and ``X-Forwarded-Proto`` are believed; empty: none, the peer address
        is the client.
    frame_ancestors : tuple of str
        CSP ``frame-ancestors`` sources: who may show the lab in a frame.
    live_sockets_per_login : int
        Live WebSockets one login may hold at once (a few tabs); refused with 4429 beyond.
    live_sockets_per_rig : int
        Live WebSockets one rig may have at once, so that one rig's watchers
        cannot take every connection the server accepts; refused with 4503 beyond.
    live_replay_samples : int
        Stored samples of the current run one socket may be sent when it
        resumes from before what memory holds: the run's first sample and its
        newest ones (``docs/live-protocol.md``, "Replay").

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
    trusted_proxies: tuple[str, ...] = ()
    frame_ancestors: tuple[str, ...] = ("'self'",)
    live_sockets_per_login: int = 4
    live_sockets_per_rig: int = 500
    live_replay_samples: int = 20_000


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
        Seconds of control per turn. A run going when they run out is not cut:
        the turn lasts until the run ends (see ``max_run_seconds``).
    max_run_seconds : float
        Longest run START accepts, in seconds of real time (samples × dt, over
        the speed-up for a twin). The default lets the paper's 2000-sample
        experiment at T = 1 s run to its end.
    idle_limit : float or None
        Seconds without a command after which control ends; ``None``: never.
    power_off_grace : float
        Seconds a rig with no controller and an empty queue stays powered.
    cooldown : CooldownPolicy
        Cool-down between turns.
    camera : str or None
        Camera of a real rig (URL or device); ``None`` draws the twin's state.
    caps : tuple of (str, float)
        The technician's upper bounds on teacher settings (``caps`` in the file:
        setting name -> largest value a teacher may set, e.g. ``max_run_seconds``).
    agent : bool
        The rig lives on a rig host that dials in (``thermolab agent``); the lab
        opens no driver for it and ``spec`` says what that host drives.
    twin_speedup : float
        A twin the lab runs runs this many times faster than real time (a
        teacher setting; its first value is the file's top-level ``speedup``).
        Not for hardware, nor for a rig on a host (the host's ``--speedup``).

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
    max_run_seconds: float = 3600.0
    caps: tuple[tuple[str, float], ...] = ()
    agent: bool = False
    twin_speedup: float = 1.0

    @property
    def lab_twin(self) -> bool:
        """``True`` for a digital twin the lab runs itself (not on a rig host)."""
        return self.kind == "sim" and not self.agent

    @property
    def speedup(self) -> float | None:
        """How many times faster than real time the rig runs, as far as the lab knows.

        ``twin_speedup`` for a twin the lab runs, 1 for hardware, ``None`` for a
        twin on a rig host (its host's ``--speedup``, which the host tells when it
        dials in: :meth:`DeviceHub.published <thermolab.lab.rigs.devices.DeviceHub.published>`).

        >>> RigConfig("t", "T", "sim", twin_speedup=50.0).speedup
        50.0
        >>> RigConfig("k", "K", "tclab").speedup, RigConfig("h", "H", "sim", agent=True).speedup
        (1.0, None)
        """
        if self.kind != "sim":
            return 1.0
        return None if self.agent else self.twin_speedup

    @property
    def rig_spec(self) -> RigSpec:
        """``spec`` parsed by the rigs layer's grammar (checked when the configuration was read).

        >>> RigConfig("k", "K", "tclab:/dev/ttyUSB0").rig_spec.argument
        '/dev/ttyUSB0'
        """
        return RigSpec.parse(self.spec)

    @property
    def kind(self) -> str:
        """``"sim"`` or ``"tclab"`` (the part of ``spec`` before the colon)."""
        return self.rig_spec.kind


class RigSettingsBoard:
    """The teacher settings in force, per rig: what :meth:`LabConfig.rig` returns.

    The lab fills it from its database at start and after every change
    (:mod:`thermolab.lab.rigs.rig_settings`); a rig it holds nothing for is the
    file's. One server serves a database (its lease), so this copy is the
    database's; every reader reads it at each check, so a change applies to
    the next turn (whose deadline is set when it starts) and the next run.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rigs: dict[str, RigConfig] = {}

    def put(self, rig: RigConfig) -> None:
        """Put ``rig`` (with its teacher settings) in force."""
        with self._lock:
            self._rigs[rig.id] = rig

    def get(self, rig_id: str) -> RigConfig | None:
        """The rig in force, if the lab put one."""
        with self._lock:
            return self._rigs.get(rig_id)


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
    speedup_override : float or None
        ``thermolab serve --speedup``: the technician's speed-up, saved at start
        as the ``twin_speedup`` of every twin the lab runs (``None``: none given).
    title : str
        Name of the lab shown to users.
    board : RigSettingsBoard
        The teacher settings in force (filled by the lab from its database);
        :meth:`rig` reads through it, ``rigs`` keeps the file's values.
    retention : RetentionPolicy
        How long people of closed courses are kept (default: until removed by hand).
    smtp : SmtpConfig or None
        The mail server of booking reminders (``None``: no reminders are sent).
    time_zone : str
        The lab's IANA time zone (``America/Sao_Paulo``; default ``UTC``): the local
        time of its reminders, and of a weekly series whose request names no zone.

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
    speedup_override: float | None = None
    title: str = "ThermoLab"
    retention: RetentionPolicy = field(default_factory=RetentionPolicy)
    smtp: SmtpConfig | None = None
    time_zone: str = "UTC"
    board: RigSettingsBoard = field(default_factory=RigSettingsBoard, compare=False, repr=False)

    def __post_init__(self) -> None:
        ids = [rig.id for rig in self.rigs]
        if not ids:
            raise ConfigError("a lab needs at least one rig")
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ConfigError(f"rig ids must be unique; repeated: {', '.join(duplicates)}")
        if not is_known_zone(self.time_zone):
            raise ConfigError(
                f"time_zone: {self.time_zone!r} is not a known IANA time zone "
                "(like America/Sao_Paulo, Europe/Lisbon or UTC)"
            )

    @property
    def database(self) -> str:
        """The database URL in use (the SQLite default when none was given)."""
        return self.database_url or default_database_url(self.data_dir)

    def rig(self, rig_id: str) -> RigConfig:
        """Return the rig called ``rig_id``, with the teacher settings in force.

        Raises
        ------
        NotFoundError
            If there is no such rig (the message lists the rigs there are).
        """
        for rig in self.rigs:
            if rig.id == rig_id:
                return self.board.get(rig_id) or rig
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
            check_speedup(speedup, "--speedup")
        return replace(
            self,
            database_url=database_url if database_url is not None else self.database_url,
            speedup_override=speedup if speedup is not None else self.speedup_override,
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


#: The rig a lab serves when no rig is declared (no file, or a file without ``[[rigs]]``).
DEFAULT_RIG = RigConfig("twin", "Digital twin of the paper's box", "sim")


#: The quick start's twin pace: the paper's first experiment (2000 samples at T = 1 s)
#: takes 33 s, well inside a turn; a teacher changes it in the rig's settings.
QUICK_START_SPEEDUP = 60.0


def default_config(data_dir: Path) -> LabConfig:
    """Return the configuration of a lab started without a file: one digital twin.

    The twin runs :data:`QUICK_START_SPEEDUP` times faster than real time, so
    that a newcomer's first run ends within a minute (a lab's file says its
    own ``speedup``; 1 unless it does).

    Examples
    --------
    >>> rig = default_config(Path("/srv/lab")).rigs[0]
    >>> rig.spec, rig.twin_speedup
    ('sim', 60.0)
    """
    quick = replace(DEFAULT_RIG, twin_speedup=QUICK_START_SPEEDUP)
    return LabConfig(data_dir=data_dir, rigs=(quick,))


def describe_value(value: object) -> str:
    """A value with its TOML type, for error messages."""
    return f"{type(value).__name__} {value!r}"


def check_number(value: object, key: str, *, minimum: float = 0.0, strict: bool = True) -> float:
    """``value`` as a finite float above ``minimum`` (at or above, unless ``strict``)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{key}: expected a number, got {describe_value(value)}")
    number = float(value)
    ok = math.isfinite(number) and (number > minimum if strict else number >= minimum)
    if not ok:
        bound = f"> {minimum:g}" if strict else f">= {minimum:g}"
        raise ConfigError(f"{key}: expected a finite number {bound}, got {value!r}")
    return number


def check_speedup(value: float, key: str) -> float:
    """A twin speed-up factor: a positive finite number."""
    return check_number(value, key, minimum=0.0, strict=True)
