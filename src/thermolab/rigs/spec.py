"""Rig specifications: the one grammar naming a rig, and what each kind of rig is.

A rig is named by one line of text, the same in the command line, the lab's
configuration file and the API: ``sim`` (the paper's twin), ``sim:PRESET``
(a twin preset), ``tclab`` (a TCLab kit, found automatically) or
``tclab:PORT``. :meth:`RigSpec.parse` is the only parser of that text.

Each kind of rig (:class:`RigKind`, one per word before the colon, in
:data:`RIG_KINDS`) declares what it is *without opening anything*: its
argument, whether it is simulated (and so follows a lab's speed-up), the
options its constructor takes with their defaults, and — through
:meth:`RigSpec.describe` — the :class:`~thermolab.rigs.contract.RigInfo` the open
rig will report (units, input range, safe input, output limit). A lab can
validate its configuration and publish every rig's ranges before powering
anything; :meth:`RigSpec.open` (and :func:`thermolab.rigs.open_rig`) then
opens it.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.rigs.clock import Clock
from thermolab.rigs.contract import InputChannel, Rig, RigInfo
from thermolab.rigs.kit_twin import KitTwinRig, check_kit_options, kit_twin_info
from thermolab.rigs.tclab import TCLabRig, tclab_info
from thermolab.rigs.twin import PRESETS, TwinParams, TwinRig, twin_info, twin_params

__all__ = ["KIT_TWIN", "RIG_KINDS", "RIG_SPECS", "RigKind", "RigSpec"]

#: The ``sim`` argument of the kit's two-heater twin (:class:`KitTwinRig`), beside the presets.
KIT_TWIN = "kit"


@dataclass(frozen=True, slots=True)
class RigKind:
    """One kind of rig: the word before the colon of a rig spec.

    Attributes
    ----------
    name : str
        The word itself: ``"sim"`` or ``"tclab"``.
    title : str
        A few words for a user interface.
    argument : str
        What follows the colon, as a help text shows it (``"PRESET"``, ``"PORT"``).
    simulated : bool
        ``True`` for a digital twin: it runs on any clock (a lab's speed-up
        applies); hardware always runs in real time.
    default_argument : str or None
        The argument of the bare word (``sim`` is ``sim:paper``); ``None``:
        the bare word means "find it" (``tclab`` auto-detects its port).
    choices : tuple of str or None
        The allowed arguments; ``None``: any non-empty text (a port).
    options : tuple of str
        The keyword options :meth:`RigSpec.open` accepts (their defaults, which
        for a twin depend on the preset, come from :meth:`RigSpec.defaults`).
    typical_dead_time : callable
        The argument's typical dead time in seconds (through
        :attr:`RigSpec.typical_dead_time`): what a live block or recursive
        identification takes when the record is not yet there to search it.

    Examples
    --------
    >>> RIG_KINDS["sim"].choices
    ('paper', 'paper-practical', 'tclab', 'kit')
    >>> "max_temperature" in RIG_KINDS["tclab"].options
    True
    """

    name: str
    title: str
    argument: str
    simulated: bool
    default_argument: str | None
    choices: tuple[str, ...] | None
    options: tuple[str, ...]
    typical_dead_time: Callable[[str | None], float] = field(repr=False)
    _defaults: Callable[[str | None], Mapping[str, Any]] = field(repr=False)
    _describe: Callable[[str | None, Mapping[str, Any]], RigInfo] = field(repr=False)
    _open: Callable[[str | None, Clock | None, int | None, Mapping[str, Any]], Rig] = field(
        repr=False
    )

    @property
    def forms(self) -> tuple[str, ...]:
        """The accepted spellings, for help texts and error messages."""
        if self.choices is None:
            return (self.name, f"{self.name}:{self.argument}")
        return (self.name, *(f"{self.name}:{choice}" for choice in self.choices))

    def check_options(self, options: Mapping[str, Any]) -> None:
        """Refuse option names this kind does not take.

        Raises
        ------
        InvalidParameterError
            Naming the unknown options and listing the allowed ones.
        """
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            label = "twin" if self.simulated else "TCLab"
            raise InvalidParameterError(
                f"unknown {label} option(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(sorted(self.options))}"
            )


def _keyword_defaults(factory: Callable[..., Any], *, skip: tuple[str, ...]) -> dict[str, Any]:
    """The keyword-only parameters of a constructor and their defaults."""
    return {
        name: p.default
        for name, p in inspect.signature(factory).parameters.items()
        if p.kind is inspect.Parameter.KEYWORD_ONLY and name not in skip
    }


def _open_twin(
    preset: str | None, clock: Clock | None, seed: int | None, options: Mapping[str, Any]
) -> Rig:
    if preset == KIT_TWIN:
        check_kit_options(dict(options))
        return KitTwinRig(clock=clock, seed=seed, **options)
    return TwinRig(preset or "paper", clock=clock, seed=seed, **options)


def _describe_twin(preset: str | None, options: Mapping[str, Any]) -> RigInfo:
    if preset == KIT_TWIN:
        check_kit_options(dict(options))
        return kit_twin_info(options.get("output_limit", _KIT_TWIN_DEFAULTS["output_limit"]))
    return twin_info(twin_params(preset or "paper", **options))


def _open_tclab(
    port: str | None, clock: Clock | None, seed: int | None, options: Mapping[str, Any]
) -> Rig:
    del seed  # hardware has no seed
    return TCLabRig(port, clock=clock, **options)


def _describe_tclab(port: str | None, options: Mapping[str, Any]) -> RigInfo:
    return tclab_info(port, options.get("max_temperature", _TCLAB_DEFAULTS["max_temperature"]))


def _twin_defaults(preset: str | None) -> Mapping[str, Any]:
    if preset == KIT_TWIN:
        return _KIT_TWIN_DEFAULTS
    params = PRESETS[preset or "paper"]
    fields = {f.name: getattr(params, f.name) for f in dataclasses.fields(TwinParams)}
    return {"realism": True, **fields}


def _twin_dead_time(preset: str | None) -> float:
    """The first order plus dead time θ of a twin: its transport delay and sensor lag.

    The sensor's lag rounds the start of a step and a first-order fit counts
    it as delay (the ``tclab`` twin: 13 s + 3 s, the kit model's 15.9 s);
    the kit's two-heater twin has no transport delay but its sensors' lag,
    which a first-order fit counts as a kit's delay (:data:`TCLAB_DEAD_TIME`).
    """
    if preset == KIT_TWIN:
        return TCLAB_DEAD_TIME
    params = PRESETS[preset or "paper"]
    return float(params.dead_time + (params.sensor_lag or 0.0))


#: A TCLab kit's dead time, seconds: the 15-17 s the kit is taught with
#: (NOTES.md §6), its lower end (a longer delay than the plant's costs more).
TCLAB_DEAD_TIME = 15.0

_TCLAB_DEFAULTS = MappingProxyType(_keyword_defaults(TCLabRig, skip=("clock",)))
_KIT_TWIN_DEFAULTS = MappingProxyType(_keyword_defaults(KitTwinRig, skip=("clock", "seed")))

#: Every kind of rig, by the word that starts its spec.
RIG_KINDS: Mapping[str, RigKind] = MappingProxyType(
    {
        "sim": RigKind(
            name="sim",
            title="digital twin",
            argument="PRESET",
            simulated=True,
            default_argument="paper",
            choices=(*PRESETS, KIT_TWIN),
            options=("realism", *(f.name for f in dataclasses.fields(TwinParams))),
            typical_dead_time=_twin_dead_time,
            _defaults=_twin_defaults,
            _describe=_describe_twin,
            _open=_open_twin,
        ),
        "tclab": RigKind(
            name="tclab",
            title="TCLab kit",
            argument="PORT",
            simulated=False,
            default_argument=None,
            choices=None,
            options=tuple(_TCLAB_DEFAULTS),
            typical_dead_time=lambda port: TCLAB_DEAD_TIME,
            _defaults=lambda port: _TCLAB_DEFAULTS,
            _describe=_describe_tclab,
            _open=_open_tclab,
        ),
    }
)

#: The accepted forms of a rig specification, for help texts and error messages.
RIG_SPECS: tuple[str, ...] = tuple(form for kind in RIG_KINDS.values() for form in kind.forms)


@dataclass(frozen=True, slots=True)
class RigSpec:
    """A parsed rig specification: a kind and its argument.

    Build one with :meth:`parse`; ``str(spec)`` is its canonical text and
    ``RigSpec.parse(str(spec)) == spec``. A bare word takes its kind's
    default argument (``sim`` is ``sim:paper``).

    Attributes
    ----------
    kind : str
        A key of :data:`RIG_KINDS`.
    argument : str or None
        The preset or port; ``None`` only where the kind allows it (``tclab``:
        auto-detect).

    Raises
    ------
    InvalidParameterError
        For an unknown kind or an argument the kind does not allow.

    Examples
    --------
    >>> spec = RigSpec.parse("sim")
    >>> spec, str(spec)
    (RigSpec(kind='sim', argument='paper'), 'sim:paper')
    >>> RigSpec.parse("tclab:/dev/ttyACM0").simulated
    False
    >>> info = RigSpec.parse("sim:tclab").describe()   # nothing is opened
    >>> info.input_range, info.input_unit, info.output_unit, info.output_limit
    ((0.0, 100.0), '%', 'degC', 90.0)
    >>> RigSpec.parse("oven")
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: unknown rig 'oven'; use one of: sim, ...
    """

    kind: str
    argument: str | None = None

    def __post_init__(self) -> None:
        text = self.kind if self.argument is None else f"{self.kind}:{self.argument}"
        rig_kind = RIG_KINDS.get(self.kind)
        if rig_kind is None:
            raise InvalidParameterError(f"unknown rig {text!r}; use one of: {', '.join(RIG_SPECS)}")
        argument = self.argument if self.argument is not None else rig_kind.default_argument
        if rig_kind.choices is not None and argument not in rig_kind.choices:
            raise InvalidParameterError(
                f"unknown {rig_kind.argument.lower()} {argument!r} in rig {text!r}; "
                f"use one of: {', '.join(rig_kind.forms)}"
            )
        if rig_kind.choices is None and argument is not None and not argument.strip():
            raise InvalidParameterError(
                f"rig {text!r} names no {rig_kind.argument.lower()}; use "
                f"{' or '.join(repr(f) for f in rig_kind.forms)}"
            )
        object.__setattr__(self, "argument", argument)

    @classmethod
    def parse(cls, text: str | RigSpec) -> RigSpec:
        """Parse ``kind`` or ``kind:argument`` (surrounding blanks ignored).

        Parameters
        ----------
        text : str or RigSpec
            The specification; a :class:`RigSpec` is returned as it is.

        Returns
        -------
        RigSpec

        Raises
        ------
        InvalidParameterError
            For an unknown kind, preset, or an empty port, listing the forms
            allowed.
        """
        if isinstance(text, RigSpec):
            return text
        if not isinstance(text, str):
            raise InvalidParameterError(
                f"a rig spec must be text such as {', '.join(RIG_SPECS)}; got {text!r}"
            )
        kind, sep, argument = text.strip().partition(":")
        return cls(kind.strip(), argument.strip() if sep else None)

    def __str__(self) -> str:
        return self.kind if self.argument is None else f"{self.kind}:{self.argument}"

    @property
    def rig_kind(self) -> RigKind:
        """The :class:`RigKind` of this spec."""
        return RIG_KINDS[self.kind]

    @property
    def simulated(self) -> bool:
        """``True`` for a digital twin (it follows a speed-up)."""
        return self.rig_kind.simulated

    @property
    def typical_dead_time(self) -> float:
        """The rig's typical dead time in seconds (0 for the paper's twins).

        Live, before the record exists to search it, the block and recursive
        methods take this delay (``order`` ``1,1,round(theta/dt)``).

        Examples
        --------
        >>> [RigSpec.parse(s).typical_dead_time for s in ("sim", "sim:tclab", "tclab", "sim:kit")]
        [0.0, 16.0, 15.0, 15.0]
        """
        return float(self.rig_kind.typical_dead_time(self.argument))

    def defaults(self) -> dict[str, Any]:
        """Return every option :meth:`open` takes with its default for this spec.

        Examples
        --------
        >>> RigSpec.parse("sim:tclab").defaults()["dead_time"]
        13.0
        >>> RigSpec.parse("tclab").defaults()["watchdog"]
        10.0
        """
        return dict(self.rig_kind._defaults(self.argument))

    @property
    def fan(self) -> InputChannel | None:
        """The disturbance fan of this rig (every twin of the paper's), or ``None``."""
        return self.actuators.get("fan")

    @property
    def actuators(self) -> Mapping[str, InputChannel]:
        """Every input besides ``u``, by name: the rig's declared further inputs.

        Each has a declared ``default``, where the rig's safe state puts it
        (:mod:`thermolab.rigs.contract`); a lab shows them and checks a hand-over
        by them.

        Examples
        --------
        >>> list(RigSpec.parse("sim").actuators), list(RigSpec.parse("sim:kit").actuators)
        (['fan'], ['q2'])
        """
        return self.describe().inputs

    def rest_state(self, **options: Any) -> dict[str, float]:
        """Every actuator's declared default: where the rig rests, and each turn and run starts.

        ``u`` is the input's safe value; the others are :attr:`actuators`'.

        Examples
        --------
        >>> RigSpec.parse("sim").rest_state()
        {'u': 0.0, 'fan': 0.0}
        >>> RigSpec.parse("tclab").rest_state()
        {'u': 0.0, 'q2': 0.0}
        """
        rest = {"u": self.describe(**options).safe_input}
        return rest | {name: spec.default for name, spec in self.actuators.items()}

    def describe(self, **options: Any) -> RigInfo:
        """Return what the rig will report once open, without opening it.

        Parameters
        ----------
        **options
            The options that would be given to :meth:`open` (a twin's
            overrides, a kit's ``max_temperature``), checked as there.

        Returns
        -------
        RigInfo
            Equal to ``self.open(**options).describe()`` (for a kit found
            automatically the name says so instead of naming the port).
        """
        self.rig_kind.check_options(options)
        return self.rig_kind._describe(self.argument, options)

    def to_dict(self) -> dict[str, Any]:
        """Return the spec and what it describes as a JSON-ready dictionary.

        Examples
        --------
        >>> d = RigSpec.parse("sim").to_dict()
        >>> d["spec"], d["kind"], d["simulated"], d["info"]["input_unit"]
        ('sim:paper', 'sim', True, 'V')
        """
        return {
            "spec": str(self),
            "kind": self.kind,
            "argument": self.argument,
            "simulated": self.simulated,
            "info": self.describe().to_dict(),
        }

    def open(self, *, clock: Clock | None = None, seed: int | None = None, **options: Any) -> Rig:
        """Open the rig (see :func:`thermolab.rigs.open_rig`)."""
        self.rig_kind.check_options(options)
        return self.rig_kind._open(self.argument, clock, seed, options)
