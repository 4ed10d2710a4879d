"""The method registry, and every entry point that must agree with it.

Modelled on python-control's ``kwargs_test.py``: the registry is walked, and
each entry point (a batch function, ``make_identifier``, a command's parser,
the runner) is asked about every declared method and setting. An entry point
that misses a setting, adds one, or disagrees on a default or a range fails
here. To cover a new entry point (the server's run schema, ``GET
/api/methods``, the browser's panel), write one ``check_*(method, setting)``
function and add it to :data:`ENTRY_POINTS`.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import typing
from collections.abc import Callable

import pytest
from hypothesis import given
from hypothesis import strategies as st

from thermolab import reproduction, simulation
from thermolab.cli import build_parser
from thermolab.errors import InvalidParameterError
from thermolab.ident import ArxOrder, Trajectory, make_identifier, recursive
from thermolab.ident import _validation as validation
from thermolab.ident.registry import (
    METHOD_NAMES,
    METHODS,
    PAPER_W0,
    SETTINGS,
    Method,
    Setting,
    check_settings,
    default_w0,
    get_method,
    owners,
    registry_json,
)
from thermolab.runner import methods as runner_methods

PAIRS = [(m, s) for m in METHODS for s in m.settings]
IDENTIFY_PAIRS = [(m, s) for m, s in PAIRS if s.role == "identify"]


def _pair_id(pair: object) -> str:
    if isinstance(pair, Method):
        return pair.name
    if isinstance(pair, Setting):
        return pair.name
    return str(pair)


def _outside(setting: Setting) -> list[float]:
    """Values just outside the declared range (none when the range is open)."""
    out = []
    if setting.minimum is not None:
        out.append(setting.minimum if setting.exclusive_minimum else setting.minimum - 1)
    if setting.maximum is not None:
        out.append(setting.maximum if setting.exclusive_maximum else setting.maximum + 1)
    if setting.type == "integer":
        out = [int(v) for v in out if float(v).is_integer()]
    return out


def _expected_default(setting: Setting) -> object:
    """A setting's default as a Python signature writes it."""
    if setting.structural_default is not None:
        return None  # resolved from the model structure
    if setting.type == "arx_order":
        return None  # None means ArxOrder(), checked in test_the_shared_declarations
    return setting.default


# -- entry points ---------------------------------------------------------------------------


def check_batch_function(method: Method, setting: Setting) -> None:
    """The batch function takes the setting, with the registry's default."""
    if setting.role == "statistics":
        params = inspect.signature(Trajectory.to_dict).parameters
        assert params[setting.name].default == setting.default
        return
    params = inspect.signature(method.batch_function()).parameters
    assert setting.name in params, f"{method.batch} lacks {setting.name}"
    assert params[setting.name].default == _expected_default(setting)


def check_make_identifier(method: Method, setting: Setting) -> None:
    """make_identifier takes the setting, applies its default and refuses its range."""
    if setting.role == "statistics":
        with pytest.raises(InvalidParameterError, match=f"unknown parameter.*{setting.name}"):
            make_identifier(method.name, 1.0, **{setting.name: setting.default})
        return
    ident = make_identifier(method.name, 1.0)
    if setting.name in ident.params and setting.structural_default is None:
        given = ident.params[setting.name]
        if setting.type == "arx_order":
            given = tuple(given.values())
        expected = setting.default
        if setting.name == "recompute_every":
            expected = ident.params["window"] - 1  # None: the window's row count (lag 0)
        assert given == expected
    for value in _outside(setting):
        with pytest.raises(InvalidParameterError, match=setting.name):
            make_identifier(method.name, 1.0, **{setting.name: value})
    if setting.type == "choice":
        with pytest.raises(InvalidParameterError, match=setting.name):
            make_identifier(method.name, 1.0, **{setting.name: "no-such-choice"})


def _subcommand(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            sub: argparse.ArgumentParser = action.choices[name]
            return sub
    raise AssertionError("no subcommands")


def _check_option(command: str, setting: Setting) -> None:
    sub = _subcommand(command)
    flag = "--" + setting.name.replace("_", "-")
    actions = {a.dest: a for a in sub._actions}
    assert setting.name in actions, f"thermolab {command} lacks {flag}"
    action = actions[setting.name]
    assert flag in action.option_strings
    assert action.default is None  # not given: the library applies the registry's default
    assert action.help is not None
    assert setting.help.replace("%", "%%") in action.help
    if setting.type == "choice":
        assert tuple(action.choices or ()) == setting.choices
    else:
        assert action.type is not None
        for value in _outside(setting):
            with pytest.raises(argparse.ArgumentTypeError, match=flag):
                action.type(str(value))  # type: ignore[operator]


def check_identify_options(method: Method, setting: Setting) -> None:
    """``thermolab identify`` has the option, and refuses it for other methods."""
    _check_option("identify", setting)


def check_run_options(method: Method, setting: Setting) -> None:
    """``thermolab run`` has an option for every identifier setting."""
    if setting.role == "identify":
        _check_option("run", setting)


def check_runner(method: Method, setting: Setting) -> None:
    """build_identifiers sends the setting to exactly the methods that take it."""
    if setting.role == "statistics":
        return
    value = setting.default
    if value is None or setting.structural_default is not None:
        value = {"recompute_every": 7, "u_initial": 0.5, "p0": 9.0}.get(setting.name, value)
    if setting.name == "p0":
        runner_methods.build_identifiers(
            METHOD_NAMES, 1.0, warm=False, options={"wlsm": {"form": "standard", "p0": value}}
        )
        return
    idents = runner_methods.build_identifiers(
        METHOD_NAMES, 1.0, warm=False, **{setting.name: value}
    )
    for name, ident in idents.items():
        assert (setting.name in ident.params) == (name in owners(setting.name))


def _run_in_property(name: str) -> tuple[dict[str, object], str]:
    """The non-null branch of a RunIn property's JSON schema, and its description."""
    from thermolab.lab.http.routers.runs import RunIn

    prop = RunIn.model_json_schema(by_alias=True)["properties"][name]
    branch = next((b for b in prop.get("anyOf", [prop]) if b.get("type") != "null"), prop)
    return branch, str(prop.get("description"))


def check_server_schema(method: Method, setting: Setting) -> None:
    """The lab's run schema takes the setting with the registry's range (or none of it).

    The lab narrows a range only in ``LAB_NARROWING``; a setting it does not
    carry gets the registry's default in the run's identifier.
    """
    from pydantic import ValidationError

    from thermolab.lab.http.routers.runs import RunIn
    from thermolab.lab.runs.request import LAB_NARROWING, RUN_SETTINGS, RunRequest
    from thermolab.lab.runs.request import build_run_identifiers as build

    if setting.role == "statistics":
        assert setting.name not in RunIn.model_fields
        return
    if setting.name == "offset":  # the registry's choices ("auto" first) and its default
        from thermolab.lab.runs.request import OFFSET_MODES

        assert setting.choices == OFFSET_MODES
        assert RunIn.model_fields["offset"].default == setting.default
        return
    run_setting = RUN_SETTINGS.get(setting.name)
    if run_setting is None:
        assert setting.name not in RunIn.model_fields
    else:
        narrowed = dataclasses.replace(setting, **LAB_NARROWING.get(setting.name, {}))
        assert run_setting == narrowed
        assert RunIn.model_fields[setting.name].default is None  # None: the registry's default
        prop, description = _run_in_property(setting.name)
        if setting.type in ("number", "integer"):
            low = "exclusiveMinimum" if narrowed.exclusive_minimum else "minimum"
            high = "exclusiveMaximum" if narrowed.exclusive_maximum else "maximum"
            assert prop.get(low) == narrowed.minimum
            assert prop.get(high) == narrowed.maximum
            for value in _outside(narrowed):
                with pytest.raises(ValidationError, match=setting.name):
                    RunIn.model_validate(
                        {"dt": 1.0, "samples": 10, "methods": [method.name], setting.name: value}
                    )
        assert setting.help in description
    if setting.structural_default is not None or setting.type == "arx_order":
        return
    idents, _ = build(RunRequest(dt=1.0, samples=10, methods=(method.name,)), "initial")
    params = idents[method.name].params
    if setting.name in params and setting.default is not None:
        assert params[setting.name] == setting.default


def check_api_methods(method: Method, setting: Setting) -> None:
    """``GET /api/methods`` lists the method and the setting as the registry declares them."""
    from thermolab.lab.http.routers.methods import MethodsOut, list_methods
    from thermolab.lab.runs.request import RUN_SETTINGS

    doc = MethodsOut.model_validate(list_methods()).model_dump(by_alias=True)
    served = next(m for m in doc["methods"] if m["name"] == method.name)
    assert {k: served[k] for k in ("title", "description", "panel")} == {
        "title": method.title,
        "description": method.description,
        "panel": method.panel,
    }
    entry = next(s for s in served["settings"] if s["name"] == setting.name)
    assert entry == setting.to_json()
    run_settings = {s["name"]: s for s in doc["runSettings"]}
    if setting.name in RUN_SETTINGS:
        assert run_settings[setting.name] == RUN_SETTINGS[setting.name].to_json()
    else:
        assert setting.name not in run_settings


ENTRY_POINTS: dict[str, Callable[[Method, Setting], None]] = {
    "batch function": check_batch_function,
    "make_identifier": check_make_identifier,
    "thermolab identify": check_identify_options,
    "thermolab run": check_run_options,
    "runner.methods": check_runner,
    "lab run schema": check_server_schema,
    "GET /api/methods": check_api_methods,
}


@pytest.mark.parametrize("entry", list(ENTRY_POINTS))
@pytest.mark.parametrize(("method", "setting"), PAIRS, ids=_pair_id)
def test_every_entry_point_agrees_with_the_registry(
    entry: str, method: Method, setting: Setting
) -> None:
    ENTRY_POINTS[entry](method, setting)


# The options of each command that are not method settings.
COMMAND_OPTIONS = {
    "identify": {"help", "file", "method", "dt", "json", "plot", "columns", "units"},
    "run": {"help", "rig", "dt", "duration", "samples", "signal", "method", "speedup", "fast",
            "seed", "out", "json", "max_output", "watchdog",
            # the channels a run identifies, and those a closed loop drives and reads
            "input", "output", "heater", "sensor",
            # closed-loop control (thermolab.control), not identifier settings
            "control", "setpoint", "kp", "ti", "td", "tune", "model", "tau_c", "pid_form",
            "adaptive", "retune_every", "max_change", "kp_range", "ti_range"},
}  # fmt: skip


@pytest.mark.parametrize("method", METHODS, ids=_pair_id)
def test_no_entry_point_takes_an_undeclared_setting(method: Method) -> None:
    declared = set(method.setting_names("identify"))
    params = inspect.signature(method.batch_function()).parameters
    # t (the sample times, to flag jitter and gaps) is data, not a setting.
    assert set(params) - set(method.data) - {"t"} == declared
    with pytest.raises(InvalidParameterError, match="unknown parameter"):
        make_identifier(method.name, 1.0, no_such_setting=1)
    assert set(make_identifier(method.name, 1.0).params) <= declared


def test_the_commands_offer_exactly_the_registered_settings() -> None:
    every = set(SETTINGS)
    identifying = {s.name for s in SETTINGS.values() if s.role == "identify"}
    for command, settings in (("identify", every), ("run", identifying)):
        dests = {a.dest for a in _subcommand(command)._actions}
        assert dests - COMMAND_OPTIONS[command] == settings, command


def test_method_names_agree_everywhere() -> None:
    from thermolab.lab.http.routers.runs import RunIn

    assert runner_methods.METHOD_NAMES == METHOD_NAMES
    items = RunIn.model_json_schema()["properties"]["methods"]["items"]
    assert tuple(items["enum"]) == METHOD_NAMES
    assert typing.get_args(reproduction.Method) == METHOD_NAMES
    action = next(a for a in _subcommand("identify")._actions if a.dest == "method")
    assert tuple(action.choices or ()) == METHOD_NAMES
    for name in METHOD_NAMES:
        assert make_identifier(name, 1.0).method == name
        assert get_method(name).online_class().method == name


def test_the_shared_declarations() -> None:
    # Concepts other layers also spell out: kept equal to the registry here.
    assert simulation.PAPER_W0 == PAPER_W0 == SETTINGS["w0"].default
    assert tuple(ArxOrder().to_dict().values()) == SETTINGS["order"].default
    assert SETTINGS["offset"].choices == (validation.AUTO_OFFSET, *validation.OFFSET_MODES)
    assert validation.OFFSET_MODES == ("initial", "fit", "none")
    assert SETTINGS["form"].choices == recursive.WLSM_FORMS == ("paper", "standard")
    from thermolab.ident import step_response

    params = inspect.signature(step_response).parameters
    for s in get_method("srm").settings:
        assert params[s.name].default == s.default
    # A shared setting is one object, referenced by every method that takes it.
    for name in ("order", "offset", "tol", "last"):
        objects = {id(s) for m in METHODS for s in m.settings if s.name == name}
        assert len(objects) == 1


def test_the_wlsm_start_is_the_papers_for_first_order_and_zeros_otherwise() -> None:
    first = make_identifier("wlsm", 1.0)
    assert first.params["w0"] == list(PAPER_W0)
    fitted = make_identifier("wlsm", 1.0, offset="fit")
    assert fitted.params["w0"] == [*PAPER_W0, 0.0]
    delayed = make_identifier("wlsm", 1.0, order=(1, 1, 3))
    assert delayed.params["w0"] == list(PAPER_W0)
    second = make_identifier("wlsm", 1.0, order=(2, 2, 0))
    assert second.params["w0"] == [0.0] * 4
    assert default_w0(3, 4) == [0.0] * 4


def test_the_batch_and_online_wlsm_start_from_the_same_default() -> None:
    import numpy as np

    from thermolab.ident import weighted_least_squares
    from thermolab.simulation import REFERENCE_MODEL

    u = np.where((np.arange(200) // 5) % 2 == 0, 4.0, 0.0)
    y = REFERENCE_MODEL.simulate(u)
    batch = weighted_least_squares(u, y, 1.0)
    ident = make_identifier("wlsm", 1.0)
    for uk, yk in zip(u, y, strict=True):
        ident.update(uk, yk)
    online = ident.trajectory()
    np.testing.assert_allclose(batch.W[0], PAPER_W0, rtol=0, atol=0)
    np.testing.assert_allclose(online.W, batch.W, rtol=0, atol=0)


def test_check_settings_fills_defaults_and_names_what_is_wrong() -> None:
    assert check_settings("blockls", {}) == {
        "block": 100,
        "order": None,  # the method's own default: the dead time searched in the record
        "offset": "auto",
        "max_delay": None,
        "expected_sign": None,
    }
    assert check_settings("wlsm", {"tol": 0.1}, role="statistics") == {"tol": 0.1, "last": 2000}
    with pytest.raises(InvalidParameterError, match=r"window = 0 is out of range; allowed: an "):
        check_settings("malsm", {"window": 0})
    with pytest.raises(InvalidParameterError, match=r"window = 2.5 is not allowed"):
        check_settings("malsm", {"window": 2.5})
    with pytest.raises(InvalidParameterError, match=r"form = 'fast' .* one of paper, standard"):
        check_settings("wlsm", {"form": "fast"})
    with pytest.raises(InvalidParameterError, match=r"w0 = \[1.0, nan\]"):
        check_settings("wlsm", {"w0": [1.0, math.nan]})
    with pytest.raises(InvalidParameterError, match=r"gamma = True"):
        check_settings("wlsm", {"gamma": True})
    with pytest.raises(InvalidParameterError, match="unknown identification method 'rls'"):
        check_settings("rls", {})


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_number_is_accepted_exactly_when_it_is_in_range(value: float) -> None:
    for setting in SETTINGS.values():
        if setting.type != "number":
            continue
        if setting.in_range(value):
            assert setting.check(value) == value
        else:
            with pytest.raises(InvalidParameterError, match=setting.name):
                setting.check(value)


def test_registry_json_has_the_api_shape() -> None:
    doc = registry_json()
    assert json.loads(json.dumps(doc, allow_nan=False)) == doc
    assert [m["name"] for m in doc["methods"]] == list(METHOD_NAMES)
    keys = {"name", "type", "default", "minimum", "maximum", "exclusiveMinimum",
            "exclusiveMaximum", "choices", "unit", "help", "role"}  # fmt: skip
    for m, declared in zip(doc["methods"], METHODS, strict=True):
        assert set(m) == {"name", "title", "description", "panel", "returns", "settings"}
        assert m["panel"] in (1, 2, 3)
        assert set(m["returns"]) <= {"final", "trajectory"}
        assert [s["name"] for s in m["settings"]] == list(declared.setting_names())
        for s in m["settings"]:
            assert set(s) == keys
    panels = {m["name"]: m["panel"] for m in doc["methods"]}
    assert panels == {"srm": 1, "lsm": 1, "blockls": 1, "malsm": 2, "wlsm": 3, "oe": 1}


def test_the_registry_loads_without_numpy_and_the_package_names_on_demand() -> None:
    import subprocess
    import sys

    import thermolab.ident as package

    code = (
        "import sys, thermolab.cli, thermolab.ident.registry;"
        "thermolab.cli.build_parser();"
        "print(sorted(m for m in ('numpy', 'scipy', 'numba') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    for name in package.__all__:
        assert getattr(package, name) is not None
    assert set(package.__all__) <= set(dir(package))
    with pytest.raises(AttributeError, match="no_such_name"):
        package.no_such_name  # noqa: B018
