"""A run request: what a controller asks for at START, and its one validation.

The bounds (:data:`MIN_DT`, :data:`MAX_DT`, :data:`MAX_SAMPLES`,
:data:`OFFSET_MODES`) are declared here; the HTTP schema publishes them and
:func:`check_request` enforces them, once. The identification methods' own
settings are built into identifiers here too (:func:`build_run_identifiers`),
so that the method registry can replace this one module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.ident.online import OnlineIdentifier
from thermolab.runner.methods import build_identifiers, parse_methods
from thermolab.signals import parse_signal
from thermolab.simulation import PAPER_W0

__all__ = [
    "MAX_DT",
    "MAX_SAMPLES",
    "MIN_DT",
    "OFFSET_METHODS",
    "OFFSET_MODES",
    "RunRequest",
    "build_run_identifiers",
    "check_request",
]

#: Most samples a run may ask for.
MAX_SAMPLES = 200_000
#: Shortest and longest sample period of a run, in seconds (the API schema publishes these).
MIN_DT = 0.01
MAX_DT = 3600.0
#: How a run's identifiers may treat the operating point: ``"auto"`` (decided from the
#: data, see :mod:`thermolab.lab.runs.operating_point`) or one of :mod:`thermolab.ident`'s modes; a
#: number is also accepted (a known ambient output).
OFFSET_MODES = ("auto", "initial", "fit", "none")
#: The paper's tables: statistics over the last 2000 samples, convergence within ±1 %.

#: Methods that regress on the output and so have an operating point to handle.
OFFSET_METHODS = ("lsm", "blockls", "malsm", "wlsm")


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
        the paper's ``W0 = [0.96329, 9.9082e-4]``.
    offset : str or float
        How the identifiers treat the operating point: ``"auto"`` (decided
        from the data, see :func:`.operating_point.choose_operating_point`),
        ``"initial"``, ``"fit"``,
        ``"none"``, or a number (the known ambient output).
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
        }


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


def build_run_identifiers(
    request: RunRequest, offset: str | float | None
) -> tuple[dict[str, OnlineIdentifier], dict[str, Any]]:
    """Build a checked request's identifiers with the chosen ``offset``.

    Returns the identifiers by method and the settings stored with the run
    (``w0`` filled in with the paper's W0 when WLSM runs without one).
    """
    methods = parse_methods(request.methods)
    options: dict[str, dict[str, Any]] = {
        m: {"offset": offset} for m in methods if m in OFFSET_METHODS
    }
    settings = request.settings()
    if "wlsm" in methods:
        w0 = list(PAPER_W0) if request.w0 is None else list(request.w0)
        options["wlsm"]["w0"] = w0
        settings["w0"] = w0
    identifiers = build_identifiers(
        methods,
        request.dt,
        window=request.window,
        block=request.block,
        gamma=request.gamma,
        pmax=request.pmax,
        options=options,
    )
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
    if any(
        isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) for v in w0
    ):
        raise InvalidParameterError(f"w0 must hold finite numbers, got {list(w0)!r}")
