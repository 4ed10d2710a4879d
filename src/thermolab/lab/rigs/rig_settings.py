"""Teacher settings per rig, stored in the database and put in force at once.

The lab's TOML file (the technician's) gives each rig's first values and the
caps a teacher cannot exceed; at the first start they are written to
``rig_settings`` (:class:`~thermolab.lab.db.settings_models.RigSettingsRow`), and
from then on the database's values are the ones in force: :meth:`load` and
every save put the rig with its settings on the configuration's board
(:class:`~thermolab.lab.config.model.RigSettingsBoard`), which
``LabConfig.rig`` reads. A change applies when it is next read: the turn limit
when the next turn starts (a turn's deadline is set then), the maximum run at
the next START, the idle limit and the cool-down at the next check; the twin
speed-up is handed to the device hub (``on_change``), which sets the twin's
clock at once when no run is going, else when the next run STARTs.

``thermolab serve --speedup X`` (``LabConfig.speedup_override``) is the
technician's: :meth:`load` saves it as the ``twin_speedup`` of every twin the
lab runs (a save by the lab file, ``updated_by`` empty).

Saves are optimistic: a change names the version it was based on, and a save
in between makes it a 409 (``settings_changed``). A value the teacher did not
change is kept even if it lies outside the teacher's range (the technician's
first value may).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy.exc import IntegrityError

from thermolab.errors import SettingNotForRigError, SettingsChangedError
from thermolab.lab.accounts.policy import Action, require_lab
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config.model import LabConfig, RigConfig
from thermolab.lab.config.teacher_settings import (
    SETTINGS,
    SettingValue,
    allowed_range,
    check_value,
    seed_values,
    settings_of,
    with_values,
)
from thermolab.lab.db import Database
from thermolab.lab.db.settings_models import RigSettingsRow

__all__ = ["RigSettings", "RigSettingsService"]

InputRange = Callable[[str], tuple[float, float] | None]
"""A rig's input range (the cool-down input's range), from the live rigs."""

OnChange = Callable[[RigConfig], None]
"""Told of a rig with its settings in force (after :meth:`RigSettingsService.load`, a save)."""


@dataclass(frozen=True, slots=True)
class RigSettings:
    """A rig's teacher settings as in force.

    Attributes
    ----------
    rig_id : str
    values : dict
        Setting name -> value in force (a cap lowers a stored value above it).
    ranges : dict
        Setting name -> the range a teacher may use on this rig (``None``: a choice).
    version : int
        Counts the saves; a change names the version it was based on.
    updated_at : datetime
    updated_by : str or None
        The teacher who saved last (``None``: the first values, from the file).
    """

    rig_id: str
    values: dict[str, SettingValue]
    ranges: dict[str, tuple[float, float] | None]
    version: int
    updated_at: datetime
    updated_by: str | None


class RigSettingsService:
    """Reads and saves the teacher settings, and keeps the configuration's board in line.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        Its ``rigs`` are the file's (first values, caps); its board gets the values in force.
    input_range : callable
        A rig's input range, for the cool-down input.
    on_change : callable, optional
        Told of each rig put in force (the device hub sets a twin's speed-up).
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        config: LabConfig,
        input_range: InputRange,
        on_change: OnChange | None = None,
    ) -> None:
        self._db = db
        self._clock = clock
        self._config = config
        self._input_range = input_range
        self._on_change = on_change
        self._lock = threading.Lock()

    def _file_rig(self, rig_id: str) -> RigConfig:
        self._config.rig(rig_id)  # an unknown rig is a 404 naming the lab's rigs
        return next(rig for rig in self._config.rigs if rig.id == rig_id)

    def _ranges(self, rig: RigConfig) -> dict[str, tuple[float, float] | None]:
        caps = dict(rig.caps)
        return {s.name: allowed_range(s, caps, self._input_range(rig.id)) for s in settings_of(rig)}

    def _in_force(self, rig: RigConfig, row: RigSettingsRow) -> RigSettings:
        """The row's values over the file's (a setting added since keeps its file value), capped."""
        values = seed_values(rig)
        values.update({k: v for k, v in row.values.items() if k in values})
        caps = dict(rig.caps)
        for name, cap in caps.items():
            value = values.get(name)
            if isinstance(value, float) and value > cap:
                values[name] = cap
        return RigSettings(
            rig.id, values, self._ranges(rig), row.version, row.updated_at, row.updated_by
        )

    def load(self) -> None:
        """Write the file's first values for rigs that have none; put every rig's in force.

        A ``serve --speedup`` is saved first as the speed-up of every twin the lab runs.
        """
        override = self._config.speedup_override
        for rig in self._config.rigs:
            with self._lock:
                row = self._row(rig)
                if override is not None and rig.lab_twin:
                    row = self._save_override(rig, row, override)
                self._put(rig, self._in_force(rig, row).values)

    def _put(self, rig: RigConfig, values: Mapping[str, SettingValue]) -> None:
        in_force = with_values(rig, values)
        self._config.board.put(in_force)
        if self._on_change is not None:
            self._on_change(in_force)

    def _save_override(self, rig: RigConfig, row: RigSettingsRow, speedup: float) -> RigSettingsRow:
        if row.values.get("twin_speedup") == speedup:
            return row
        with self._db.write() as session:
            locked = session.get(RigSettingsRow, rig.id, with_for_update=True)
            assert locked is not None  # _row seeded it
            if locked.values.get("twin_speedup") != speedup:
                locked.values = {**locked.values, "twin_speedup": speedup}
                locked.version += 1
                locked.updated_at = self._clock.now()
                locked.updated_by = None
                session.flush()
            return locked

    def _row(self, rig: RigConfig) -> RigSettingsRow:
        with self._db.read() as session:
            row = session.get(RigSettingsRow, rig.id)
        if row is not None:
            return row
        seeded = RigSettingsRow(
            rig_id=rig.id,
            values=seed_values(rig),
            version=1,
            updated_at=self._clock.now(),
            updated_by=None,
        )
        try:
            with self._db.write() as session:
                session.add(seeded)
        except IntegrityError:  # another lab on this database seeded it first
            with self._db.read() as session:
                found = session.get(RigSettingsRow, rig.id)
            assert found is not None
            return found
        return seeded

    def get(self, rig_id: str, who: Principal) -> RigSettings:
        """A rig's settings in force (teachers only).

        Raises
        ------
        AccessDeniedError
            For a student.
        NotFoundError
            For an unknown rig.
        """
        who.require_teacher("see a rig's settings")
        rig = self._file_rig(rig_id)
        return self._in_force(rig, self._row(rig))

    def update(
        self,
        rig_id: str,
        who: Principal,
        values: Mapping[str, object],
        version: int,
    ) -> RigSettings:
        """Save ``values`` (some or all settings) over version ``version``; put them in force.

        Raises
        ------
        AccessDeniedError
            For anyone but a lab administrator.
        SettingRangeError
            A changed value outside its range (the message names it); nothing is saved.
        SettingNotForRigError
            A setting the rig does not have (the twin speed-up of hardware); nothing is saved.
        SettingsChangedError
            The settings were saved since ``version``.
        """
        require_lab(who, Action.RIG_SETTINGS_EDIT)
        rig = self._file_rig(rig_id)
        with self._lock:
            current = self._in_force(rig, self._row(rig))
            if version != current.version:
                raise SettingsChangedError(
                    f"the settings of {rig_id} were saved since version {version} (now "
                    f"{current.version}, by {current.updated_by or 'the lab file'}); load them "
                    "again and repeat the change"
                )
            checked = dict(current.values)
            for name, value in values.items():
                setting = SETTINGS[name]
                if name not in current.values:
                    raise SettingNotForRigError(
                        name,
                        f"rig {rig_id!r} has no setting {name} (only the digital twins the lab "
                        "runs itself have it: a real rig runs in real time, and a rig host's "
                        "twin at its host's --speedup)",
                    )
                if value == current.values[name]:
                    continue
                checked[name] = check_value(setting, value, current.ranges[name])
            now = self._clock.now()
            with self._db.write() as session:
                row = session.get(RigSettingsRow, rig_id, with_for_update=True)
                if row is None or row.version != version:
                    raise SettingsChangedError(
                        f"the settings of {rig_id} were saved since version {version}; load "
                        "them again and repeat the change"
                    )
                row.values = checked
                row.version = version + 1
                row.updated_at = now
                row.updated_by = who.username
                session.flush()
                saved = self._in_force(rig, row)
            self._put(rig, saved.values)
            return saved
