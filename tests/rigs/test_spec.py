"""RigSpec and RigKind: one grammar, and what each rig is without opening it."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from thermolab.errors import InvalidParameterError
from thermolab.rigs import PRESETS, RIG_KINDS, RIG_SPECS, RigSpec, open_rig
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.tclab_emulator import TCLabEmulator

_PORTS = st.text(st.characters(codec="ascii", exclude_characters=":", min_codepoint=33), min_size=1)
_SPECS = st.one_of(
    st.sampled_from(list(PRESETS)).map(lambda p: RigSpec("sim", p)),
    st.just(RigSpec("tclab")),
    _PORTS.map(lambda port: RigSpec("tclab", port)),
)


@given(_SPECS)
def test_text_round_trips(spec: RigSpec) -> None:
    assert RigSpec.parse(str(spec)) == spec
    assert RigSpec.parse(f"  {spec}  ") == spec


@pytest.mark.parametrize("text", RIG_SPECS)
def test_every_listed_form_parses(text: str) -> None:
    spec = RigSpec.parse(text)
    assert spec.rig_kind is RIG_KINDS[text.partition(":")[0]]


def test_bare_words_take_their_defaults() -> None:
    assert RigSpec.parse("sim") == RigSpec("sim", "paper") == RigSpec("sim")
    assert RigSpec.parse("tclab").argument is None
    assert RigSpec.parse("tclab:/dev/ttyACM0").argument == "/dev/ttyACM0"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("oven", r"unknown rig 'oven'; use one of: sim, sim:paper, .*tclab:PORT"),
        ("sim:oven", r"unknown preset 'oven' in rig 'sim:oven'; use one of: sim, sim:paper,"),
        ("tclab:", r"rig 'tclab:' names no port; use 'tclab' or 'tclab:PORT'"),
        ("tclab:  ", r"names no port"),
        ("", r"unknown rig ''"),
    ],
)
def test_bad_specs_name_what_is_allowed(text: str, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        RigSpec.parse(text)


def test_non_text_is_refused() -> None:
    with pytest.raises(InvalidParameterError, match="must be text"):
        RigSpec.parse(3)  # type: ignore[arg-type]


@pytest.mark.parametrize("preset", list(PRESETS))
def test_a_twin_describes_itself_as_it_will_be_once_open(preset: str) -> None:
    spec = RigSpec("sim", preset)
    assert spec.simulated
    with open_rig(spec, clock=VirtualClock(), seed=1) as rig:
        assert spec.describe() == rig.describe()
    with open_rig(spec, clock=VirtualClock(), input_max=5.0, output_limit=None) as rig:
        assert spec.describe(input_max=5.0, output_limit=None) == rig.describe()


def test_a_kit_describes_itself_without_opening_the_port() -> None:
    spec = RigSpec.parse("tclab:/dev/does-not-exist")
    info = spec.describe(max_temperature=70.0)  # no serial port is touched
    assert not spec.simulated
    assert (info.input_range, info.input_unit, info.output_unit) == ((0.0, 100.0), "%", "degC")
    assert (info.safe_input, info.output_limit) == (0.0, 70.0)
    clock = VirtualClock()
    with TCLabEmulator(clock=clock) as emulator:
        spec = RigSpec("tclab", emulator.port)
        with spec.open(clock=clock, reset_wait=0.0, watchdog=None) as rig:
            assert spec.describe() == rig.describe()


def test_defaults_are_the_constructors() -> None:
    assert RigSpec.parse("sim:tclab").defaults()["ambient"] == 21.0
    assert RigSpec.parse("sim").defaults()["realism"] is True
    tclab = RigSpec.parse("tclab").defaults()
    assert set(tclab) == set(RIG_KINDS["tclab"].options)
    assert (tclab["timeout"], tclab["max_temperature"]) == (1.0, 90.0)


def test_options_are_checked_before_anything_opens() -> None:
    with pytest.raises(InvalidParameterError, match=r"unknown twin option.*allowed: adc_range"):
        RigSpec.parse("sim").describe(watchdog=1.0)
    with pytest.raises(InvalidParameterError, match="unknown TCLab option"):
        RigSpec.parse("tclab:/dev/null").describe(noise_std=1.0)
