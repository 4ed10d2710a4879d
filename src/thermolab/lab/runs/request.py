"""A run request: what a controller asks for at START, its one validation, its operating point.

The run's own bounds (:data:`MIN_DT`, :data:`MAX_DT`, :data:`MAX_SAMPLES`) are
declared here. The identification methods, their settings, defaults and
ranges are the registry's (:mod:`thermolab.ident.registry`):
:data:`RUN_SETTINGS` picks the settings a run request carries and is the one
place the lab narrows a registry range (:data:`LAB_NARROWING`, each with its
reason). The HTTP schema (:class:`thermolab.lab.http.routers.runs.RunIn`) is built
from :data:`RUN_SETTINGS` and :func:`check_request` enforces it, once;
``tests/ident/test_registry.py`` checks both against the registry.

The operating point: the lab does not judge the rig (no clock, no "time since
the last run"); it is a property of the record, decided from the data by the
library's one procedure (:func:`thermolab.ident.operating_point.decide_operating_point`,
``offset="auto"``). The lab passes the request's ``offset`` to the
identifiers; each method's result then reports the handling used and the
operating point found (its ``extras``). What the lab stores with the run is
what was asked, what the identifiers were given and why
(:class:`OperatingPoint`, :func:`choose_operating_point`).

The run's length: the rig's ``max_run_seconds`` bounds it in real time (the
twin's own speed-up counted), :func:`check_run_length`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.ident.online import OnlineIdentifier
from thermolab.ident.registry import METHODS, SETTINGS, Setting, owners
from thermolab.lab.config import LabConfig
from thermolab.lab.config.teacher_settings import SettingValue, course_override
from thermolab.lab.runs.control import ControlRequest
from thermolab.runner.methods import build_identifiers, parse_methods
from thermolab.signals import parse_signal

__all__ = [
    "AUTO",
    "LAB_NARROWING",
    "LIVE_DEAD_TIME_METHODS",
    "MAX_DT",
    "MAX_SAMPLES",
    "MIN_DT",
    "OFFSET_METHODS",
    "OFFSET_MODES",
    "RUN_SETTINGS",
    "OperatingPoint",
    "RunPlan",
    "RunRequest",
    "build_run_identifiers",
    "check_request",
    "check_run_length",
    "choose_operating_point",
    "live_dead_time",
    "plan_run",
    "run_seconds",
]

#: Most samples a run may ask for.
MAX_SAMPLES = 200_000
#: Shortest and longest sample period of a run, in seconds (the API schema publishes these).
MIN_DT = 0.01
MAX_DT = 3600.0
#: How a run's identifiers may treat the operating point: ``"auto"`` (decided from the
#: data, see :func:`choose_operating_point`) or one of
#: the registry's ``offset`` choices; a number is also accepted (a known ambient output).
OFFSET_MODES: tuple[str, ...] = SETTINGS["offset"].choices

#: Methods that regress on the output and so have an operating point to handle.
OFFSET_METHODS: tuple[str, ...] = owners("offset")

#: Methods with live estimates whose dead time the registry leaves to the structure
#: (``order`` not given: searched offline, none live): the lab gives them the rig's
#: typical dead time (:func:`live_dead_time`). LSM searches it at END itself.
LIVE_DEAD_TIME_METHODS: tuple[str, ...] = tuple(
    m.name
    for m in METHODS
    if "trajectory" in m.returns
    and SETTINGS["order"] in m.settings
    and SETTINGS["order"].structural_default is not None
    and SETTINGS["order"].structural_default(2, 2) is None
)

#: Where the lab deliberately accepts less than the registry allows, and why. Every
#: other bound of a run setting is the registry's.
LAB_NARROWING: Mapping[str, Mapping[str, Any]] = MappingProxyType(
    {
        # The lab runs WLSM in the paper's form, where gamma = 1 has no meaning (alpha = 0).
        "gamma": {"maximum": 1.0, "exclusive_maximum": True},
        # A window or block longer than the longest run could never fill.
        "window": {"maximum": MAX_SAMPLES},
        "block": {"maximum": MAX_SAMPLES},
    }
)

#: The method settings a run request carries (each the registry's, narrowed by
#: :data:`LAB_NARROWING`); the others keep the registry's default. ``offset`` is
#: apart: its modes are the registry's choices (:data:`OFFSET_MODES`).
RUN_SETTINGS: Mapping[str, Setting] = MappingProxyType(
    {
        name: dataclasses.replace(SETTINGS[name], **LAB_NARROWING.get(name, {}))
        for name in ("window", "block", "gamma", "pmax", "w0")
    }
)


@dataclass(frozen=True, slots=True)
class RunRequest:
    """What a controller asks for at START (the three panels of the paper).

    Attributes
    ----------
    dt : float
        Sample period, seconds (:data:`MIN_DT` to :data:`MAX_DT`).
    samples : int
        Samples to take, 1 to :data:`MAX_SAMPLES` (END may stop earlier).
    signal : str or None
        Input signal (``step:0:10@10``, ``square:4:6:0.1``...); ``None`` for a
        manual set point.
    setpoint : float or None
        The manual input at START (with no signal; default the safe input).
    methods : tuple of str
        Identification methods (``srm``, ``lsm``, ``blockls``, ``malsm``, ``wlsm``).
    window, block : int or None
        MALSM window and block-LSM block, in samples.
    gamma, pmax : float or None
        WLSM forgetting factor and initial covariance.
    w0 : tuple of float or None
        WLSM initial parameters ``[a0, b0]`` of the first-order model (``[a0,
        b0, c0]`` with ``offset="fit"``, ``c0`` the constant term); ``None`` is
        the registry's default (the paper's W0).
    control : ControlRequest or None
        A PID on the output (a closed-loop run, :mod:`.control`); ``None``: open loop.
    offset : str or float
        How the identifiers treat the operating point: ``"auto"`` (decided
        from the data, see :func:`choose_operating_point`),
        ``"initial"``, ``"fit"``,
        ``"none"``, or a number (the known ambient output).
    input, output : str
        The pair identified (:mod:`thermolab.runner.pair`): ``"u"``, ``"y"`` (the
        default) or the rig's further channels (a kit's ``"q2"``, ``"t2"``).
    """

    dt: float
    samples: int
    signal: str | None = None
    setpoint: float | None = None
    methods: tuple[str, ...] = ("srm", "lsm")
    window: int | None = None
    block: int | None = None
    gamma: float | None = None
    pmax: float | None = None
    w0: tuple[float, ...] | None = None
    offset: str | float = "auto"
    control: ControlRequest | None = None
    input: str = "u"
    output: str = "y"

    def settings(self) -> dict[str, Any]:
        """The request as stored with the run."""
        return {
            "dt": self.dt,
            "samples": self.samples,
            "signal": self.signal,
            "setpoint": self.setpoint,
            "methods": list(self.methods),
            "window": self.window,
            "block": self.block,
            "gamma": self.gamma,
            "pmax": self.pmax,
            "w0": None if self.w0 is None else list(self.w0),
            "offset": self.offset,
            "control": None if self.control is None else self.control.settings(),
            "input": self.input,
            "output": self.output,
        }


#: The request's offset that leaves the decision to the data.
AUTO = "auto"


@dataclass(frozen=True, slots=True)
class OperatingPoint:
    """How a run's identifiers handle the operating point, and why (stored with the run).

    Attributes
    ----------
    asked : str or float
        The request's ``offset`` (``"auto"`` unless the user chose).
    used : str, float or None
        The offset the identifiers were built with (``"auto"``: each decides
        from the record and reports it in its result); ``None`` when no chosen
        method regresses on the output (the step response finds its own
        baseline).
    reason : str
        The choice, in words (shown to the user).

    Examples
    --------
    >>> OperatingPoint("fit", "fit", "fit, as asked").to_dict()["used"]
    'fit'
    """

    asked: str | float
    used: str | float | None
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (``asked``, ``used``, ``reason``)."""
        return {"asked": self.asked, "used": self.used, "reason": self.reason}


def choose_operating_point(asked: str | float, methods: Sequence[str]) -> OperatingPoint:
    """Decide what the run's identifiers are given as ``offset``.

    Parameters
    ----------
    asked : str or float
        The request's ``offset``.
    methods : sequence of str
        The run's methods (only LSM, block LSM, MALSM and WLSM use an offset).

    Returns
    -------
    OperatingPoint

    Raises
    ------
    InvalidParameterError
        For an explicit offset when no chosen method uses one.

    Examples
    --------
    >>> choose_operating_point("initial", ["lsm"]).reason
    'initial, as asked'
    >>> choose_operating_point("auto", ["srm"]).used is None
    True
    """
    if not any(m in OFFSET_METHODS for m in methods):
        if asked != AUTO:
            raise InvalidParameterError(
                f"offset is a setting of {', '.join(OFFSET_METHODS)}, none of which is among "
                f"the methods ({', '.join(methods)}); the step response finds its own baseline"
            )
        return OperatingPoint(
            asked, None, "no chosen method uses it (the step response finds its baseline)"
        )
    if asked != AUTO:
        return OperatingPoint(asked, asked, f"{asked}, as asked")
    return OperatingPoint(
        asked,
        AUTO,
        "auto: each method decides from the record (at ambient, settled under an input, "
        "or moving) and reports the handling used and the operating point found",
    )


def check_request(request: RunRequest, limits: tuple[float, float]) -> dict[str, Any]:
    """Check a run request against the lab's bounds and the rig's input range.

    This is the one place the lab checks a run's settings (``dt``, samples,
    signal or set point, methods, offset, ``w0``); the HTTP schema only
    publishes the bounds.

    Returns
    -------
    dict
        The experiment's input: ``{"signal": Signal}``, ``{"set_point": u}`` or ``{}``.

    Raises
    ------
    InvalidParameterError
        Naming the setting, what was given and what is allowed.

    Examples
    --------
    >>> check_request(RunRequest(dt=1.0, samples=10, setpoint=5.0), (0.0, 10.0))
    {'set_point': 5.0}
    >>> check_request(RunRequest(dt=0.0, samples=10), (0.0, 10.0))
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: dt must be between 0.01 and 3600 seconds, got 0.0
    """
    if not (math.isfinite(request.dt) and MIN_DT <= request.dt <= MAX_DT):
        raise InvalidParameterError(
            f"dt must be between {MIN_DT:g} and {MAX_DT:g} seconds, got {request.dt!r}"
        )
    if not 1 <= request.samples <= MAX_SAMPLES:
        raise InvalidParameterError(
            f"samples must be between 1 and {MAX_SAMPLES}, got {request.samples!r}"
        )
    methods = parse_methods(request.methods)
    for name, setting in RUN_SETTINGS.items():
        setting.check(getattr(request, name))
    _check_offset(request.offset)
    if request.w0 is not None:
        _check_w0(request.w0, request.offset, methods)
    if request.signal is not None and request.setpoint is not None:
        raise InvalidParameterError("give either a signal or a setpoint, not both")
    if request.signal is not None:
        return {"signal": parse_signal(request.signal, limits)}
    if request.setpoint is not None:
        low, high = limits
        if not (math.isfinite(request.setpoint) and low <= request.setpoint <= high):
            raise InvalidParameterError(
                f"setpoint {request.setpoint!r} is outside the rig's input range "
                f"[{low:g}, {high:g}]"
            )
        return {"set_point": request.setpoint}
    return {}


def live_dead_time(request: RunRequest, method: str, typical_dead_time: float) -> int:
    """The delay in samples ``method`` is given live: the rig's typical dead time.

    Rounded to whole samples at the run's ``dt``, and shortened where a block or
    window would otherwise hold no regression rows (``delay + 5`` samples at most
    a window: the first order with a constant term).
    """
    if method not in LIVE_DEAD_TIME_METHODS:
        return 0
    delay = max(0, round(typical_dead_time / request.dt))
    size = {"blockls": request.block, "malsm": request.window}.get(method)
    if method in ("blockls", "malsm"):
        size = (
            size
            if size is not None
            else SETTINGS["block" if method == "blockls" else "window"].default
        )
        delay = min(delay, max(0, int(size) - 5))
    return delay


def build_run_identifiers(
    request: RunRequest, offset: str | float | None, typical_dead_time: float = 0.0
) -> tuple[dict[str, OnlineIdentifier], dict[str, Any]]:
    """Build a checked request's identifiers with the chosen ``offset``.

    ``typical_dead_time`` (seconds): the rig's (:attr:`thermolab.rigs.RigSpec.typical_dead_time`),
    given as the delay of the block and recursive methods
    (:data:`LIVE_DEAD_TIME_METHODS`), which cannot search it live.

    Returns the identifiers by method and the settings stored with the run
    (``w0`` filled in with the start WLSM used: the registry's default when
    none was given; ``dead_time``: per such method, the handling and the delay
    used, ``{"handling": "rig", "delay": samples, "theta": seconds}``).
    """
    methods = parse_methods(request.methods)
    options: dict[str, dict[str, Any]] = {
        m: {"offset": offset} for m in methods if m in OFFSET_METHODS
    }
    settings = request.settings()
    dead_time: dict[str, dict[str, Any]] = {}
    for m in methods:
        if m not in LIVE_DEAD_TIME_METHODS:
            continue
        delay = live_dead_time(request, m, typical_dead_time)
        dead_time[m] = {"handling": "rig", "delay": delay, "theta": delay * request.dt}
        if delay:  # delay 0 is the registry's live order (1, 1, 0): left to it
            options.setdefault(m, {})["order"] = (1, 1, delay)
    if dead_time:
        settings["dead_time"] = dead_time
    identifiers = build_identifiers(
        methods,
        request.dt,
        options=options,
        **{name: getattr(request, name) for name in RUN_SETTINGS},
    )
    if "wlsm" in identifiers:
        settings["w0"] = list(identifiers["wlsm"].params["w0"])
    return identifiers, settings


def _check_offset(offset: object) -> None:
    if isinstance(offset, str):
        if offset not in OFFSET_MODES:
            raise InvalidParameterError(
                f"offset must be one of {', '.join(repr(m) for m in OFFSET_MODES)} or a number "
                f"(the known ambient output), got {offset!r}"
            )
        return
    if isinstance(offset, bool) or not isinstance(offset, int | float) or not math.isfinite(offset):
        raise InvalidParameterError(
            f"offset must be one of {', '.join(repr(m) for m in OFFSET_MODES)} or a finite "
            f"number (the known ambient output), got {offset!r}"
        )


def _check_w0(w0: Sequence[float], offset: str | float, methods: Sequence[str]) -> None:
    if "wlsm" not in methods:
        raise InvalidParameterError(
            f"w0 is a setting of wlsm, which is not among the methods ({', '.join(methods)})"
        )
    sizes = (2, 3) if offset == "fit" else (2,)
    if len(w0) not in sizes:
        allowed = (
            "2 entries [a0, b0] or 3 [a0, b0, c0] (c0: the constant term)"
            if offset == "fit"
            else "2 entries [a0, b0] (3, with the constant term c0, only with offset 'fit')"
        )
        raise InvalidParameterError(f"w0 must have {allowed}, got {len(w0)}")


@dataclass(frozen=True, slots=True)
class RunPlan:
    """A checked request, ready to run: what START needs from this module, in one value.

    Attributes
    ----------
    inputs : dict
        The experiment's input (:func:`check_request`'s result).
    identifiers : dict
        The online identifiers by method.
    settings : dict
        The settings stored with the run (``w0`` filled in).
    operating_point : OperatingPoint
        What the identifiers were given as ``offset``, and why.
    """

    inputs: dict[str, Any]
    identifiers: dict[str, OnlineIdentifier]
    settings: dict[str, Any]
    operating_point: OperatingPoint


def plan_run(
    request: RunRequest, limits: tuple[float, float], typical_dead_time: float = 0.0
) -> RunPlan:
    """Check ``request`` against the rig's input range ``limits`` and build its identifiers.

    ``typical_dead_time``: the rig's, in seconds (:func:`build_run_identifiers`).

    :func:`check_request`, :func:`choose_operating_point` and
    :func:`build_run_identifiers`, in that order.

    Raises
    ------
    InvalidParameterError
        Naming the setting, what was given and what is allowed.
    """
    inputs = check_request(request, limits)
    point = choose_operating_point(request.offset, parse_methods(request.methods))
    identifiers, settings = build_run_identifiers(request, point.used, typical_dead_time)
    return RunPlan(inputs, identifiers, settings, point)


def run_seconds(samples: int, dt: float, speedup: float | None) -> float:
    """The real time a run of ``samples`` × ``dt`` takes on a rig running ``speedup`` times
    faster than real time (:attr:`PublishedRig.speedup
    <thermolab.lab.config.PublishedRig.speedup>`: a twin's teacher setting, which the run
    STARTed now keeps, or its host's; ``None``, a host not heard yet, counts as real time).

    >>> run_seconds(2000, 1.0, 50.0), run_seconds(2000, 1.0, None)
    (40.0, 2000.0)
    """
    return samples * dt / (speedup or 1.0)


def check_run_length(
    request: RunRequest,
    rig_id: str,
    config: LabConfig,
    speedup: float | None,
    limits: tuple[tuple[str, SettingValue], ...] = (),
) -> float:
    """Return how long the run lasts (real seconds), if the rig's ``max_run_seconds`` allows it.

    ``speedup``: the rig's pace (:func:`run_seconds`). ``limits``: a course's, in
    force during its slot on the rig (its ``max_run_seconds``, lowered to the rig's
    cap, replaces the rig's).

    Raises
    ------
    InvalidParameterError
        For a longer run, giving the most samples allowed at its dt.
    """
    length = run_seconds(request.samples, request.dt, speedup)
    rig = config.rig(rig_id)
    longest = rig.max_run_seconds
    course = dict(limits).get("max_run_seconds")
    if isinstance(course, int | float):
        capped = course_override(float(course), dict(rig.caps).get("max_run_seconds"))
        assert isinstance(capped, float)
        longest = capped
    if length > longest:
        per_sample = length / request.samples
        raise InvalidParameterError(
            f"a run of {request.samples} samples at dt = {request.dt:g} s lasts "
            f"{length:g} s, longer than rig {rig_id!r} allows ({longest:g} s): at this dt "
            f"at most {int(longest / per_sample + 1e-9)} samples"
        )
    return length
