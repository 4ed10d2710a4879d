"""The lab's configuration: which rigs it serves, their limits, the access policy.

* :mod:`.model` — the configuration's dataclasses and their defaults;
* :mod:`.toml_file` — :func:`load_config`, the TOML reader that names every error's key;
* :mod:`.rig_kinds` — the rig-spec grammar and each kind's units and ranges;
* :mod:`.retention` — how long people of closed courses are kept;
* :mod:`.time_zones` — the one check of an IANA zone's name (the lab's ``time_zone``,
  a weekly series' zone, a spreadsheet's ``tz``).
"""

from thermolab.lab.config.model import (
    DATABASE_FILE,
    AccessPolicy,
    CooldownPolicy,
    LabConfig,
    RigConfig,
    default_config,
    default_database_url,
    resolve_data_dir,
)
from thermolab.lab.config.retention import RetentionPolicy
from thermolab.lab.config.rig_kinds import PublishedRig, parse_rig_spec, published_defaults
from thermolab.lab.config.toml_file import load_config

__all__ = [
    "DATABASE_FILE",
    "AccessPolicy",
    "CooldownPolicy",
    "LabConfig",
    "PublishedRig",
    "RetentionPolicy",
    "RigConfig",
    "default_config",
    "default_database_url",
    "load_config",
    "parse_rig_spec",
    "published_defaults",
    "resolve_data_dir",
]
