"""The lab's TOML configuration: defaults, a full file, and errors that name the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from thermolab.errors import ConfigError, NotFoundError
from thermolab.lab.config import (
    CooldownPolicy,
    RetentionPolicy,
    default_config,
    load_config,
    parse_rig_spec,
    resolve_data_dir,
)
from thermolab.lab.config.model import QUICK_START_SPEEDUP
from thermolab.lab.rigs.devices import published_defaults

FULL = """
title = "Room 2.14"
time_zone = "America/Sao_Paulo"
database_url = "postgresql://lab@db/thermolab"
speedup = 20

[access]
client_timeout = 20
session_lifetime = 3600
login_failures_per_user = 3
cookie_samesite = "lax"
cookie_secure = "always"

[rig_defaults]
control_time_limit = 600
idle_limit = 0
cooldown = { mode = "ambient", tolerance = 0.2 }

[[rigs]]
id = "box-1"
title = "The paper's box"
spec = "sim:paper-practical"
input_range = [0, 10]

[[rigs]]
id = "kit-1"
spec = "tclab:/dev/ttyUSB0"
control_time_limit = 120
idle_limit = 60
power_off_grace = 0
cooldown = { mode = "none" }
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "lab.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_without_a_file_the_lab_has_one_twin_and_sqlite_in_the_data_dir(tmp_path: Path) -> None:
    config = default_config(tmp_path)
    (rig,) = config.rigs
    assert (rig.id, rig.spec, rig.control_time_limit, rig.idle_limit) == ("twin", "sim", 300, 120)
    assert config.database == f"sqlite:///{tmp_path / 'thermolab.sqlite3'}"
    assert config.access.client_timeout == 15.0
    assert config.time_zone == "UTC"


def test_a_full_file(tmp_path: Path) -> None:
    config = load_config(write(tmp_path, FULL), tmp_path)
    assert config.title == "Room 2.14"
    assert config.time_zone == "America/Sao_Paulo"
    assert {rig.twin_speedup for rig in config.rigs} == {20.0}  # the twins' first speed-up
    assert config.database == "postgresql://lab@db/thermolab"
    assert (config.access.client_timeout, config.access.session_lifetime) == (20.0, 3600.0)
    assert (config.access.cookie_samesite, config.access.cookie_secure) == ("lax", "always")
    box, kit = config.rigs
    assert (box.title, box.input_range, box.control_time_limit, box.idle_limit) == (
        "The paper's box",
        (0.0, 10.0),
        600.0,
        None,
    )
    assert box.cooldown == CooldownPolicy(mode="ambient", tolerance=0.2)
    assert (kit.title, kit.kind, kit.control_time_limit, kit.idle_limit) == (
        "kit-1",
        "tclab",
        120,
        60,
    )
    assert (kit.power_off_grace, kit.cooldown.enabled) == (0.0, False)
    assert config.rig("kit-1") is kit
    with pytest.raises(NotFoundError, match="no rig called 'nope'; the lab has: box-1, kit-1"):
        config.rig("nope")


def test_overrides_from_the_command_line(tmp_path: Path) -> None:
    config = load_config(write(tmp_path, FULL), tmp_path).with_overrides(
        database_url="sqlite:////x.db", speedup=5
    )
    assert (config.database, config.speedup_override) == ("sqlite:////x.db", 5)
    with pytest.raises(ConfigError, match="--speedup: expected a finite number > 0, got -1"):
        config.with_overrides(speedup=-1)


A = "[[rigs]]\nid='a'\nspec='sim'\n"  # the smallest valid file


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (A + "colour='red'\n", r"rigs\[0\]\.colour: unknown key"),
        (
            A + "control_time_limit=-5\n",
            r"rigs\[0\]\.control_time_limit: expected a finite number > 0, got -5",
        ),
        (
            A + "control_time_limit='long'\n",
            r"rigs\[0\]\.control_time_limit: expected a number, got str 'long'",
        ),
        (
            "[[rigs]]\nid='a'\nspec='lab'\n",
            r"rigs\[0\]\.spec: unknown rig 'lab'; use one of: sim, sim:paper",
        ),
        (
            "[[rigs]]\nid='a'\nspec='sim:nope'\n",
            r"rigs\[0\]\.spec: unknown preset 'nope' in rig 'sim:nope'",
        ),
        ("[[rigs]]\nid='A b'\nspec='sim'\n", r"rigs\[0\]\.id: 'A b' is not a valid rig id"),
        ("[[rigs]]\nspec='sim'\n", r"rigs\[0\]\.id: required"),
        (A + "input_range=[5, 1]\n", r"rigs\[0\]\.input_range: min must be below max"),
        (A + "input_range=[5]\n", r"rigs\[0\]\.input_range: expected \[min, max\]"),
        (A + A, "rig ids must be unique; repeated: a"),
        ("rigs = []\n", "rigs: expected one or more"),
        (
            "[rig_defaults]\nmax_run_seconds=0\n",
            r"rig_defaults\.max_run_seconds: expected a finite number > 0, got 0",
        ),
        (A + "max_run_seconds='1h'\n", r"rigs\[0\]\.max_run_seconds: expected a number"),
        (
            "[access]\ncookie_samesite='none'\n" + A,
            r"access\.cookie_samesite: expected one of 'strict', 'lax', got 'none'",
        ),
        ("[access]\nlogin_window=0\n" + A, r"access\.login_window: expected a finite number > 0"),
        (
            "[access]\nlogin_failures_per_user=2.5\n" + A,
            r"access\.login_failures_per_user: expected a whole number",
        ),
        (
            "[rig_defaults]\ncooldown={mode='cold'}\n" + A,
            r"rig_defaults\.cooldown\.mode: expected one of 'none', 'ambient'",
        ),
        (
            "[rig_defaults]\ncooldown={mode='ambient', speed=3}\n" + A,
            r"rig_defaults\.cooldown\.speed: unknown key",
        ),
        ("speedup=0\n" + A, "speedup: expected a finite number > 0"),
        ("[retention]\nmonths=0\n", r"retention\.months: expected a finite number >= 1, got 0"),
        ("[retention]\nmonths=2000\n", r"retention\.months: expected at most 1200, got 2000"),
        ("[retention]\nmonths=1.5\n", r"retention\.months: expected a whole number"),
        (
            "[retention]\naction='archive'\n",
            r"retention\.action: expected one of 'pseudonymise', 'delete', got 'archive'",
        ),
        (
            "[retention]\ndays=30\n",
            r"retention\.days: unknown key \(allowed here: months, action\)",
        ),
        (
            "time_zone = 'Mars/Olympus'\n",
            r"time_zone: 'Mars/Olympus' is not a known IANA time zone \(like America/Sao_Paulo",
        ),
        ("time_zone = 'America/Sao Paulo'\n", r"time_zone: 'America/Sao Paulo' is not a known"),
        ("time_zone = -3\n", "time_zone: expected a non-empty string, got -3"),
        ("rigs = 3\n", "rigs: expected one or more"),
        ("[[rigs]\n", "not valid TOML"),
    ],
)
def test_errors_name_the_key_and_what_is_allowed(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as info:
        load_config(write(tmp_path, text), tmp_path)
    assert str(info.value).startswith(str(tmp_path / "lab.toml"))
    assert "\n" not in str(info.value)


def test_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "missing.toml", tmp_path)


def test_the_configured_range_must_lie_inside_the_rigs_own(tmp_path: Path) -> None:
    config = load_config(
        write(tmp_path, "[[rigs]]\nid='a'\nspec='sim:tclab'\ninput_range=[0, 150]\n"), tmp_path
    )
    with pytest.raises(ConfigError, match=r"input_range \[0, 150\] goes beyond .* \[0, 100\] %"):
        published_defaults(config.rigs[0])


def test_rig_specs() -> None:
    assert parse_rig_spec("sim") == ("sim", "paper")  # the rigs layer's default preset
    assert parse_rig_spec("sim:tclab") == ("sim", "tclab")
    assert parse_rig_spec("tclab") == ("tclab", None)
    assert parse_rig_spec("tclab:/dev/ttyACM0") == ("tclab", "/dev/ttyACM0")
    with pytest.raises(ConfigError, match="names no port"):
        parse_rig_spec("tclab:")
    with pytest.raises(ConfigError, match="unknown rig 'oven'"):
        parse_rig_spec("oven")


def test_data_dir_from_the_option_the_environment_or_a_per_user_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("THERMOLAB_DATA_DIR", str(tmp_path / "env"))
    assert resolve_data_dir(tmp_path / "opt") == tmp_path / "opt"
    assert resolve_data_dir() == tmp_path / "env"
    monkeypatch.delenv("THERMOLAB_DATA_DIR")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert resolve_data_dir() == tmp_path / "xdg" / "thermolab"


def test_rig_defaults_apply_to_the_default_twin(tmp_path: Path) -> None:
    # A teacher changes one limit without declaring the rig: the others keep their defaults.
    config = load_config(write(tmp_path, "[rig_defaults]\ncontrol_time_limit = 900\n"), tmp_path)
    default = default_config(tmp_path).rigs[0]
    (twin,) = config.rigs
    assert (twin.id, twin.spec, twin.control_time_limit) == ("twin", "sim", 900.0)
    assert (twin.idle_limit, twin.max_run_seconds) == (default.idle_limit, default.max_run_seconds)
    config = load_config(write(tmp_path, "[rig_defaults]\nmax_run_seconds = 7200\n"), tmp_path)
    assert config.rigs[0].max_run_seconds == 7200.0
    assert config.rigs[0].control_time_limit == default.control_time_limit


def test_max_run_seconds_is_a_rig_limit(tmp_path: Path) -> None:
    text = "[rig_defaults]\nmax_run_seconds = 600\n[[rigs]]\nid='a'\nspec='sim'\n"
    text += "[[rigs]]\nid='b'\nspec='sim'\nmax_run_seconds = 5000\n"
    config = load_config(write(tmp_path, text), tmp_path)
    assert [rig.max_run_seconds for rig in config.rigs] == [600.0, 5000.0]
    # The default lets the paper's 2000-sample experiment at T = 1 s run in real time.
    assert default_config(tmp_path).rigs[0].max_run_seconds >= 2000 * 1.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[access]\nmax_body_bytes=100\n",
            r"access\.max_body_bytes: expected a finite number >= 1024",
        ),
        (
            "[access]\nlive_sockets_per_rig=0\n",
            r"access\.live_sockets_per_rig: expected a finite number >= 1",
        ),
        (
            "[access]\nlive_replay_samples=1\n",
            r"access\.live_replay_samples: expected a finite number >= 2",
        ),
        ("speedup='fast'\n", "speedup: expected a number, got str 'fast'"),
        ("speedup=true\n", "speedup: expected a number, got bool True"),
        ("title=''\n", "title: expected a non-empty string"),
        ("[access]\nlogin_window=nan\n", r"access\.login_window: expected a finite number"),
        (A + "input_range=[0, 'x']\n", r"rigs\[0\]\.input_range\[1\]: expected a number"),
        (A + "input_range=[0, 1, 2]\n", r"rigs\[0\]\.input_range: expected \[min, max\]"),
        ("access = 3\n", "access: expected a table, got int 3"),
        ("[rigs]\nid='a'\n", r"rigs: expected one or more \[\[rigs\]\] tables"),
    ],
)
def test_pydantic_errors_keep_the_key_path_in_one_line(
    tmp_path: Path, text: str, message: str
) -> None:
    with pytest.raises(ConfigError, match=message) as info:
        load_config(write(tmp_path, text), tmp_path)
    assert "\n" not in str(info.value)


def test_a_key_left_out_inherits_the_one_declared_default(tmp_path: Path) -> None:
    text = "[rig_defaults]\ncooldown = { mode = 'ambient', tolerance = 0.2 }\n"
    text += A + "cooldown = { max_seconds = 100 }\n"
    (rig,) = load_config(write(tmp_path, text), tmp_path).rigs
    assert rig.cooldown == CooldownPolicy(mode="ambient", tolerance=0.2, max_seconds=100.0)
    assert (
        load_config(write(tmp_path, "title='x'\n"), tmp_path).access
        == default_config(tmp_path).access
    )


def test_the_live_socket_limits_are_access_keys(tmp_path: Path) -> None:
    text = "[access]\nlive_sockets_per_login = 2\nlive_sockets_per_rig = 30\n"
    text += "live_replay_samples = 5000\n"
    access = load_config(write(tmp_path, text), tmp_path).access
    assert (access.live_sockets_per_login, access.live_sockets_per_rig) == (2, 30)
    assert access.live_replay_samples == 5000
    default = default_config(tmp_path).access
    assert (default.live_sockets_per_login, default.live_sockets_per_rig) == (4, 500)
    assert default.live_replay_samples == 20_000


def test_the_retention_period_from_the_file_then_the_environment(tmp_path: Path) -> None:
    assert default_config(tmp_path).retention == RetentionPolicy(None, "pseudonymise")
    config = load_config(write(tmp_path, "[retention]\nmonths = 24\n"), tmp_path)
    assert config.retention == RetentionPolicy(24, "pseudonymise")
    environ = {"THERMOLAB_RETENTION_MONTHS": " 18 ", "THERMOLAB_RETENTION_ACTION": "delete"}
    assert config.retention.with_environment(environ) == RetentionPolicy(18, "delete")
    empty = {"THERMOLAB_RETENTION_MONTHS": "", "THERMOLAB_RETENTION_ACTION": ""}
    assert config.retention.with_environment(empty) == config.retention  # empty is unset
    for name, value, message in (
        ("THERMOLAB_RETENTION_MONTHS", "two years", "expected a whole number of months"),
        (
            "THERMOLAB_RETENTION_MONTHS",
            "0",
            "expected a whole number of months from 1 to 1200, got 0",
        ),
        ("THERMOLAB_RETENTION_ACTION", "archive", "expected pseudonymise or delete"),
    ):
        with pytest.raises(ConfigError, match=f"^{name}: {message}"):
            config.retention.with_environment({name: value})


def test_the_quick_start_twin_runs_the_papers_first_experiment_within_a_minute(
    tmp_path: Path,
) -> None:
    # No file (the README's quick start): one twin whose pace fits the paper's first
    # experiment, 2000 samples at T = 1 s, in under a minute of wall time (issue #24).
    (quick,) = default_config(tmp_path).rigs
    assert (quick.lab_twin, quick.speedup) == (True, QUICK_START_SPEEDUP)
    assert 2000 * 1.0 / QUICK_START_SPEEDUP < 60.0
    # A lab's file keeps its own pace: real time unless it says, with or without [[rigs]].
    assert load_config(write(tmp_path, 'title = "Lab"\n'), tmp_path).rigs[0].twin_speedup == 1.0
    declared = "[[rigs]]\nid = 'twin'\nspec = 'sim'\n[[rigs]]\nid = 'kit'\nspec = 'tclab'\n"
    declared += "[[rigs]]\nid = 'host'\nspec = 'sim'\nagent = true\n"
    paces = [rig.speedup for rig in load_config(write(tmp_path, declared), tmp_path).rigs]
    assert paces == [1.0, 1.0, None]  # hardware in real time; a host's twin: its host's
