"""open_rig: the rig specification shared by the command line and the server."""

from __future__ import annotations

import pytest

from thermolab.errors import InvalidParameterError, RigError
from thermolab.rigs import RIG_SPECS, TCLabRig, TwinRig, open_rig
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab_emulator import TCLabEmulator


@pytest.mark.parametrize(
    ("spec", "preset"),
    [
        ("sim", "paper"),
        ("sim:paper", "paper"),
        ("sim:paper-practical", "paper-practical"),
        (" sim:tclab ", "tclab"),
    ],
)
def test_sim_specs_open_twins(spec: str, preset: str) -> None:
    with open_rig(spec, clock=VirtualClock(), seed=3) as rig:
        assert isinstance(rig, TwinRig)
        assert rig.params.name == preset


def test_twin_options_pass_through() -> None:
    with open_rig("sim", clock=VirtualClock(), noise_std=0.01, ambient=1.0) as rig:
        assert isinstance(rig, TwinRig)
        assert (rig.params.noise_std, rig.params.ambient) == (0.01, 1.0)


def test_seed_makes_twins_repeatable() -> None:
    def first(seed: int) -> float:
        with open_rig("sim:paper-practical", clock=VirtualClock(), seed=seed) as rig:
            return rig.read().value

    assert first(8) == first(8)


def test_tclab_with_a_port_opens_the_driver() -> None:
    clock = VirtualClock()
    with (
        TCLabEmulator(clock=clock) as emulator,
        open_rig(f"tclab:{emulator.port}", clock=clock, seed=1, reset_wait=0.0) as rig,
    ):
        assert isinstance(rig, TCLabRig)
        assert rig.port == emulator.port


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("lab", "unknown rig 'lab'; use one of: sim, sim:paper"),
        ("sim:oven", "unknown preset 'oven' in rig 'sim:oven'; use one of: sim, sim:paper"),
        ("tclab:", "names no port"),
        ("", "unknown rig ''"),
    ],
)
def test_unknown_specs_are_refused_with_the_choices(spec: str, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        open_rig(spec)


def test_unknown_options_are_refused() -> None:
    with pytest.raises(InvalidParameterError, match="unknown TCLab option"):
        open_rig("tclab:/dev/null", noise_std=1.0)
    with pytest.raises(InvalidParameterError, match="unknown twin option"):
        open_rig("sim", watchdog=3.0)


def test_a_missing_port_is_a_rig_error() -> None:
    with pytest.raises(RigError, match="cannot open serial port"):
        open_rig("tclab:/dev/does-not-exist", reset_wait=0.0)


def test_the_spec_list_names_every_form() -> None:
    assert RIG_SPECS == (
        "sim",
        "sim:paper",
        "sim:paper-practical",
        "sim:tclab",
        "sim:kit",
        "tclab",
        "tclab:PORT",
    )
