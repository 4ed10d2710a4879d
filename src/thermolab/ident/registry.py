"""The identification methods and their settings, each declared once.

Every entry point reads this module instead of spelling a method out again:
:func:`~thermolab.ident.online.make_identifier` (allowed settings, defaults,
checks), the batch functions' default values, :mod:`thermolab.runner.methods`
(method names, which method owns which setting), the ``thermolab identify``
and ``thermolab run`` options, :mod:`thermolab.reproduction`, and — through
:func:`registry_json` — the lab server's ``GET /api/methods`` and the
browser's panels. ``tests/ident/test_registry.py`` walks the registry and fails
when an entry point disagrees on a name, a default or a range.

The module imports nothing heavy (no NumPy, no kernels), so a command line can
build its options from it and still answer ``--help`` at once; each method's
implementations are named by ``"module:attribute"`` and imported on first use.

How to add a setting
    Declare one :class:`Setting` below (name, type, default, range, unit, help;
    the type is in :mod:`thermolab.ident._setting`) and add it to the
    ``settings`` of every :class:`Method` that takes it; then read it in the
    method's implementation (the online identifier's ``from_settings`` and the
    batch function, whose signature default is ``SETTINGS["name"].default``). The
    CLI options, the checks and the JSON follow. A setting that only shapes the
    statistics of a trajectory (like ``tol``) gets ``role="statistics"``: the
    identifiers never see it.

How to add a method
    Write its batch function and an :class:`~thermolab.ident.online.OnlineIdentifier`
    subclass with a ``from_settings(dt, settings)`` class method, then declare
    one :class:`Method` in :data:`METHODS` naming both.

Notes
-----
Where entry points disagreed before the registry existed, the registry
decided: WLSM's ``gamma`` and ``pmax`` now default to the paper's WLSM(1)
(0.96, 1e4) in the library too (they were required there), and ``w0``
defaults to the paper's ``W0`` for the first-order ``[a, b]`` regressor (the
server's choice; the library and the CLI started from zeros), so a record
exported from the lab and identified again gives the trajectory shown on the
page. Other structures start from zeros (see :func:`default_w0`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from thermolab.errors import InvalidParameterError

from ._setting import Role, Setting, SettingType

__all__ = [
    "METHODS",
    "METHOD_NAMES",
    "PAPER_W0",
    "SETTINGS",
    "Method",
    "Setting",
    "SettingType",
    "check_settings",
    "default_w0",
    "get_method",
    "owners",
    "registry_json",
]


#: The paper's initial WLSM parameters ``[a, b]`` (section 4; the reference
#: model's own ``a`` and ``b`` to five digits). :data:`thermolab.simulation.PAPER_W0`
#: is the same pair for the simulation layer, which cannot import this one; the
#: registry test keeps them equal.
PAPER_W0: tuple[float, float] = (0.96329, 9.9082e-4)

# -- settings ---------------------------------------------------------------------------

_ORDER = Setting(
    "order", "arx_order", (1, 1, 0),
    "ARX order: output lags, input lags, dead time in samples beyond one; 1,1,0 is eq. 4 "
    "(default: 1,1 with the dead time searched over 0..max_delay in the whole record; "
    "live, 1,1,0 unless given)",
    metavar="NA,NB,DELAY", structural_default=lambda n_dynamic, n_params: None,
)  # fmt: skip
_OFFSET = Setting(
    "offset", "offset", "auto",
    "operating point: auto decides from the data (initial or fit), initial removes the "
    "first output sample, fit estimates a constant, none is the paper's raw form, a number "
    "is the known ambient output",
    choices=("auto", "initial", "fit", "none"), unit="V",
    metavar="auto|none|initial|fit|VALUE",
)  # fmt: skip
_MAX_DELAY = Setting(
    "max_delay", "integer", None,
    "longest dead time searched (default: 60 samples, at most a tenth of the record; "
    "0 turns the search off)",
    minimum=0, maximum=1000, unit="samples", metavar="N",
)  # fmt: skip
_THETA = Setting(
    "theta", "number", None, "the dead time, if known (default: estimated up to max_delay)",
    minimum=0.0, unit="s", metavar="S",
)  # fmt: skip
_EXPECTED_SIGN = Setting(
    "expected_sign", "integer", None,
    "the gain's sign, 1 (a heater: the output rises with the input) or -1; a gain of the "
    "other sign is flagged (default: not checked)",
    minimum=-1, maximum=1, metavar="SIGN",
)  # fmt: skip
_HOLDOUT = Setting(
    "holdout", "number", 0.3,
    "fraction of the record held out for the held-out fit % (0 skips it)",
    minimum=0.0, maximum=0.5, metavar="F",
)  # fmt: skip
_BLOCK = Setting(
    "block", "integer", 100,
    "samples per block: one estimate at the end of each block (at least the model's "
    "lag + 1 + its number of parameters: 3 for first order)",
    minimum=3, unit="samples", metavar="N",
)  # fmt: skip
_WINDOW = Setting(
    "window", "integer", 100,
    "samples in the moving window (at least the model's lag + 1 + its number of "
    "parameters: 3 for first order)",
    minimum=3, unit="samples", metavar="N",
)  # fmt: skip
_RECOMPUTE = Setting(
    "recompute_every", "integer", None,
    "regression rows between exact recomputations of the window sums "
    "(default: the window's row count)",
    minimum=1, unit="rows", metavar="N",
)  # fmt: skip
_GAMMA = Setting(
    "gamma", "number", 0.96,
    "forgetting factor γ; 1 (no forgetting) only with form standard",
    minimum=0.0, maximum=1.0, exclusive_minimum=True, metavar="G",
)  # fmt: skip
_PMAX = Setting(
    "pmax", "number", 1.0e4, "initial diagonal of P (the paper's pmax)",
    minimum=0.0, exclusive_minimum=True, metavar="P",
)  # fmt: skip
_W0 = Setting(
    "w0", "number_list", PAPER_W0,
    "initial parameters: the paper's W0 for the first-order [a, b] regressor, "
    "zeros for other orders",
    metavar="A,B", structural_default=lambda n_dynamic, p: default_w0(n_dynamic, p),
)  # fmt: skip
_FORM = Setting(
    "form", "choice", "paper", "formulation: the paper's eqs. 13-15, or textbook RLS",
    choices=("paper", "standard"),
)  # fmt: skip
_P0 = Setting(
    "p0", "covariance", None,
    "form standard only: initial covariance P0 = p0·I (default pmax·I)",
    minimum=0.0, exclusive_minimum=True, metavar="P0",
)  # fmt: skip
_U_INITIAL = Setting(
    "u_initial", "number", None,
    "the input before the record began (default: the first input sample)",
    unit="V", metavar="U",
)  # fmt: skip
_MIN_STEP = Setting(
    "min_step", "number", 1.0, "steps smaller than this are flagged (the paper's rule)",
    minimum=0.0, unit="V", metavar="V",
)  # fmt: skip
_MIN_SAMPLES = Setting(
    "min_samples", "integer", 2000,
    "records shorter than this are flagged (the paper's rule; 0 turns the check off)",
    minimum=0, unit="samples", metavar="N",
)  # fmt: skip
_SETTLE = Setting(
    "settle_time_constants", "number", 4.0,
    "time constants after the step for the record to count as settled",
    minimum=0.0, exclusive_minimum=True, metavar="N",
)  # fmt: skip
_TOL = Setting(
    "tol", "number", 0.01, "relative band for converged_at; 0.01 is ±1 %",
    minimum=0.0, exclusive_minimum=True, role="statistics", metavar="TOL",
)  # fmt: skip
_LAST = Setting(
    "last", "integer", 2000, "samples the statistics cover, counted from the end",
    minimum=1, unit="samples", role="statistics", metavar="N",
)  # fmt: skip

#: Every setting by name (a shared one, like ``order``, appears once).
_ALL_SETTINGS = (
    _ORDER, _OFFSET, _MAX_DELAY, _THETA, _EXPECTED_SIGN, _HOLDOUT,
    _BLOCK, _WINDOW, _RECOMPUTE, _GAMMA, _PMAX, _W0, _FORM, _P0,
    _U_INITIAL, _MIN_STEP, _MIN_SAMPLES, _SETTLE, _TOL, _LAST,
)  # fmt: skip
SETTINGS: Mapping[str, Setting] = MappingProxyType({s.name: s for s in _ALL_SETTINGS})

# -- methods ----------------------------------------------------------------------------


def _resolve(path: str) -> Any:
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module, __package__), attribute)


@dataclass(frozen=True)
class Method:
    """One identification method: what it is, what it returns, how it runs, what it takes.

    Parameters
    ----------
    name : str
        The short name every entry point uses (``"wlsm"``).
    title : str
        For headings: ``"Weighted least squares (WLSM)"``.
    description : str
        One line on what the method does.
    panel : int
        The paper's panel the method belongs to (1: SRM, LSM and block LSM;
        2: MALSM; 3: WLSM).
    returns : tuple of str
        ``"final"`` (one final estimate) and/or ``"trajectory"`` (an estimate
        per sample or block).
    batch : str
        The batch function, ``"module:function"`` relative to :mod:`thermolab.ident`.
    online : str
        The :class:`~thermolab.ident.online.OnlineIdentifier` subclass, likewise.
    settings : tuple of Setting
        What the method takes, in the order the command line shows them.
    data : tuple of str
        The batch function's leading positional arguments, from ``"t"``,
        ``"u"``, ``"y"`` and ``"dt"``.
    """

    name: str
    title: str
    description: str
    panel: int
    returns: tuple[str, ...]
    batch: str
    online: str
    settings: tuple[Setting, ...] = field(default=())
    data: tuple[str, ...] = ("u", "y", "dt")

    def batch_function(self) -> Callable[..., Any]:
        """The batch implementation (imported on first use)."""
        function: Callable[..., Any] = _resolve(self.batch)
        return function

    def online_class(self) -> Any:
        """The online implementation, an ``OnlineIdentifier`` subclass (imported on first use)."""
        return _resolve(self.online)

    def setting_names(self, role: Role | None = None) -> tuple[str, ...]:
        """Names of the method's settings (of one ``role`` only, if given)."""
        return tuple(s.name for s in self.settings if role is None or s.role == role)

    def defaults(self, role: Role = "identify") -> dict[str, Any]:
        """``{name: default}`` of the settings of ``role``."""
        return {s.name: s.default for s in self.settings if s.role == role}

    def to_json(self) -> dict[str, Any]:
        """This method as ``registry_json()`` lists it."""
        return {
            "name": self.name,
            "title": self.title,
            "description": self.description,
            "panel": self.panel,
            "returns": list(self.returns),
            "settings": [s.to_json() for s in self.settings],
        }


_MODEL = (_ORDER, _OFFSET)
_TRUST = (_EXPECTED_SIGN,)
_SUMMARY = (_TOL, _LAST)

#: The methods, in the paper's order.
METHODS: tuple[Method, ...] = (
    Method(
        "srm", "Step response (SRM)",
        "K from the final value and tau from the 63.2 % crossing of one step",
        1, ("final",), ".step:step_response", "._online_final:_StepResponse",
        (_U_INITIAL, _MIN_STEP, _MIN_SAMPLES, _SETTLE), data=("t", "u", "y"),
    ),
    Method(
        "lsm", "Batch least squares (LSM)",
        "least squares over the whole record (eq. 12), with standard errors and fits",
        1, ("final",), ".batch:least_squares", "._online_final:_LeastSquares",
        (*_MODEL, _MAX_DELAY, _HOLDOUT, *_TRUST),
    ),
    Method(
        "blockls", "Block least squares (LSM(2), LSM(3))",
        "least squares over consecutive blocks: one estimate per block",
        1, ("final", "trajectory"), ".blocks:block_least_squares",
        "._online_final:_BlockLeastSquares", (_BLOCK, *_MODEL, _MAX_DELAY, *_TRUST, _LAST),
    ),
    Method(
        "malsm", "Moving-window least squares (MALSM)",
        "least squares over a window of the latest samples: one estimate per sample",
        2, ("final", "trajectory"), ".recursive:moving_window_least_squares",
        "._online_recursive:_MovingWindow",
        (_WINDOW, _RECOMPUTE, *_MODEL, _MAX_DELAY, *_TRUST, *_SUMMARY),
    ),
    Method(
        "wlsm", "Weighted least squares (WLSM)",
        "recursive least squares with a forgetting factor: one estimate per sample",
        3, ("final", "trajectory"), ".recursive:weighted_least_squares",
        "._online_recursive:_Weighted",
        (_GAMMA, _PMAX, _W0, _FORM, _P0, *_MODEL, _MAX_DELAY, *_TRUST, *_SUMMARY),
    ),
    Method(
        "oe", "Output error (OE)",
        "K, tau and the dead time that best simulate the record (free-run error): "
        "unbiased by measurement noise, unlike the ARX methods",
        1, ("final",), ".oe:output_error", "._online_final:_OutputError",
        (_THETA, _MAX_DELAY, *_TRUST),
    ),
)  # fmt: skip

#: The method names, in the paper's order.
METHOD_NAMES: tuple[str, ...] = tuple(m.name for m in METHODS)

_BY_NAME: Mapping[str, Method] = MappingProxyType({m.name: m for m in METHODS})


def get_method(name: str) -> Method:
    """The declared method called ``name``.

    Raises
    ------
    InvalidParameterError
        For an unknown name (the message lists the known ones).

    Examples
    --------
    >>> get_method("malsm").title
    'Moving-window least squares (MALSM)'
    """
    try:
        return _BY_NAME[name]
    except (KeyError, TypeError):
        raise InvalidParameterError(
            f"unknown identification method {name!r}; allowed: {', '.join(METHOD_NAMES)}"
        ) from None


def check_settings(
    method: str, settings: Mapping[str, Any], role: Role = "identify"
) -> dict[str, Any]:
    """Check a user's settings for ``method`` against the declarations.

    Parameters
    ----------
    method : str
        A name from :data:`METHOD_NAMES`.
    settings : mapping
        Setting names to values; ``None`` stands for the default.
    role : {"identify", "statistics"}, optional
        Which of the method's settings are allowed (default: the identifier's).

    Returns
    -------
    dict
        Every setting of that role: the checked value given, else the default
        (``None`` for a setting with a ``structural_default``, which the
        implementation resolves once it knows the model structure).

    Raises
    ------
    InvalidParameterError
        For an unknown method, a setting the method does not take (the message
        lists those it does), or a value outside the declared type or range.

    Examples
    --------
    >>> check_settings("malsm", {"window": 50})  # doctest: +NORMALIZE_WHITESPACE
    {'window': 50, 'recompute_every': None, 'order': None, 'offset': 'auto',
     'max_delay': None, 'expected_sign': None}
    >>> check_settings("lsm", {"window": 50})
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: unknown parameter for lsm: window; allowed: order, ...
    """
    m = get_method(method)
    allowed = m.setting_names(role)
    unknown = sorted(set(settings) - set(allowed))
    if unknown:
        raise InvalidParameterError(
            f"unknown parameter{'s' if len(unknown) > 1 else ''} for {method}: "
            f"{', '.join(unknown)}; allowed: {', '.join(allowed) if allowed else 'none'}"
        )
    out: dict[str, Any] = {}
    for s in m.settings:
        if s.role == role:
            value = s.check(settings.get(s.name))
            # A structure-dependent default is left as None for the implementation.
            out[s.name] = s.default if value is None and s.structural_default is None else value
    return out


def owners(setting: str) -> tuple[str, ...]:
    """The methods that take ``setting``, in the paper's order.

    Examples
    --------
    >>> owners("offset")
    ('lsm', 'blockls', 'malsm', 'wlsm')
    >>> owners("max_delay")
    ('lsm', 'blockls', 'malsm', 'wlsm', 'oe')
    """
    return tuple(m.name for m in METHODS if setting in m.setting_names())


def default_w0(n_dynamic: int, n_params: int) -> list[float]:
    """WLSM's starting parameters when ``w0`` is not given.

    :data:`PAPER_W0` for the first-order ``[a, b]`` regressor (two dynamic
    parameters: ``na = nb = 1``, any dead time), followed by 0 for a fitted
    constant; zeros for any other structure, where the paper's pair has no
    meaning.

    Parameters
    ----------
    n_dynamic : int
        ``na + nb``.
    n_params : int
        All parameters (``n_dynamic`` plus 1 with ``offset="fit"``).

    Examples
    --------
    >>> default_w0(2, 2), default_w0(2, 3), default_w0(3, 3)
    ([0.96329, 0.00099082], [0.96329, 0.00099082, 0.0], [0.0, 0.0, 0.0])
    """
    if n_dynamic == 2:
        return [*SETTINGS["w0"].default, *([0.0] * (n_params - 2))]
    return [0.0] * n_params


def registry_json() -> dict[str, Any]:
    """The registry as JSON for ``GET /api/methods`` and the browser's panels.

    Returns
    -------
    dict
        ``{"methods": [{"name", "title", "description", "panel", "returns",
        "settings": [{"name", "type", "default", "minimum", "maximum",
        "exclusiveMinimum", "exclusiveMaximum", "choices", "unit", "help",
        "role"}]}]}``, with ``null`` where a key does not apply.

    Examples
    --------
    >>> import json
    >>> doc = registry_json()
    >>> [m["name"] for m in doc["methods"]]
    ['srm', 'lsm', 'blockls', 'malsm', 'wlsm', 'oe']
    >>> wlsm = doc["methods"][4]
    >>> wlsm["title"], wlsm["panel"], wlsm["returns"]
    ('Weighted least squares (WLSM)', 3, ['final', 'trajectory'])
    >>> print(json.dumps(wlsm["settings"][0]))  # doctest: +NORMALIZE_WHITESPACE
    {"name": "gamma", "type": "number", "default": 0.96, "minimum": 0.0, "maximum": 1.0,
     "exclusiveMinimum": true, "exclusiveMaximum": false, "choices": null, "unit": null,
     "help": "forgetting factor \\u03b3; 1 (no forgetting) only with form standard",
     "role": "identify"}
    """
    return {"methods": [m.to_json() for m in METHODS]}
