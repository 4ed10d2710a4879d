"""A run records its rig's further channels (a kit's T2, Q2) and sets a further input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thermolab.control import PIDGains
from thermolab.errors import InvalidParameterError
from thermolab.records import read_record
from thermolab.rigs import KitTwinRig, TwinRig, VirtualClock
from thermolab.runner import ControlLoop, CsvRecorder, Experiment

from .conftest import HookedKit


def test_a_q2_step_mid_run_is_recorded_and_warms_t2_not_the_run_input() -> None:
    rig = HookedKit(clock=VirtualClock(), seed=2)
    exp = Experiment(rig, 1.0, 900, set_point=0.0)
    assert [c.name for c in exp.channels][-2:] == ["t2", "q2"]
    rig.hooks[100] = lambda: exp.set_further("q2", 80.0)
    result = exp.run()
    q2, t2 = result.extra["q2"], result.extra["t2"]
    on = int(np.flatnonzero(q2)[0])
    assert on in (100, 101)  # set at a sample's instant, from then on
    assert set(q2[on:]) == {80.0}
    assert set(result.u) == {0.0}  # heater 1 untouched
    assert t2[-1] > t2[on] + 10.0  # heater 2 warms sensor 2...
    assert t2[-1] - t2[on] > 3 * (result.y[-1] - result.y[on])  # ...far more than sensor 1
    assert rig.level("q2") == 0.0  # the run's end put heater 2 off
    with pytest.raises(InvalidParameterError, match="takes 0-100 %"):
        Experiment(rig, 1.0, 2).set_further("q2", 101.0)


def test_the_csv_record_has_the_further_columns(tmp_path: Path) -> None:
    rig = KitTwinRig(clock=VirtualClock(), seed=2)
    channels = Experiment(rig, 1.0, 5, set_point=10.0).channels
    path = tmp_path / "kit.csv"
    Experiment(rig, 1.0, 5, set_point=10.0, recorder=CsvRecorder(path, channels=channels)).run()
    record = read_record(path)
    assert len(record.columns["t2"]) == len(record.columns["q2"]) == 5
    assert set(record.columns["q2"]) == {0.0}
    assert 15.0 < record.columns["t2"][0] < 30.0  # the room's temperature


def test_a_rig_without_further_channels_records_what_it_did() -> None:
    rig = TwinRig("paper", clock=VirtualClock(), seed=0)
    assert "q2" not in [c.name for c in Experiment(rig, 1.0, 2).channels]
    assert "fan" not in [c.name for c in Experiment(rig, 1.0, 2).channels]  # open loop: t,u,y
    loop = ControlLoop(PIDGains(1.0, 10.0), setpoint=0.5)
    with pytest.raises(InvalidParameterError, match="no input 'q2'; its further inputs: fan"):
        Experiment(rig, 1.0, 2, controller=loop).set_further("q2", 10.0)
