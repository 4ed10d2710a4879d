"""Build the online identifiers of a run from the settings a user gives.

The command line and the lab server both describe a run's methods the same
way — a list of names from :data:`METHOD_NAMES` and a few settings (window,
block, γ, pmax, …) — and :func:`build_identifiers` turns that into the
:class:`~thermolab.ident.online.OnlineIdentifier` objects an
:class:`~thermolab.runner.Experiment` feeds. Names, defaults and which method
owns which setting come from :mod:`thermolab.ident.registry`. A setting that no
chosen method uses is an error, not silently ignored.

The identifiers' compiled kernels load (or compile) on their first call, which
takes up to a few seconds; inside a real-time loop that would make the first
samples late and could trip the watchdog. :func:`build_identifiers` therefore
warms each method up on a short synthetic record before returning, so START is
followed by samples on time.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.ident.online import OnlineIdentifier, make_identifier
from thermolab.ident.registry import METHOD_NAMES, SETTINGS, owners

__all__ = [
    "METHOD_NAMES",
    "build_identifiers",
    "parse_methods",
    "warm_up",
    "warm_up_every_method",
]


def parse_methods(text: str | Iterable[str]) -> tuple[str, ...]:
    """Parse a comma-separated list of method names (order kept, duplicates dropped).

    Parameters
    ----------
    text : str or iterable of str
        ``"srm,lsm"``, ``"all"``, or names already split.

    Returns
    -------
    tuple of str
        Known method names.

    Raises
    ------
    InvalidParameterError
        For an empty list or an unknown name (the message lists the known ones).

    Examples
    --------
    >>> parse_methods("srm, LSM,srm")
    ('srm', 'lsm')
    >>> parse_methods("all") == METHOD_NAMES
    True
    >>> parse_methods("rls")
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: unknown method 'rls'; allowed: srm, lsm, ...
    """
    parts = text.split(",") if isinstance(text, str) else list(text)
    names = [p.strip().lower() for p in parts if p.strip()]
    if names == ["all"]:
        return METHOD_NAMES
    if not names:
        raise InvalidParameterError(
            f"no method given; choose from {', '.join(METHOD_NAMES)} (comma-separated)"
        )
    unknown = [n for n in names if n not in METHOD_NAMES]
    if unknown:
        raise InvalidParameterError(
            f"unknown method {unknown[0]!r}; allowed: {', '.join(METHOD_NAMES)}"
        )
    return tuple(dict.fromkeys(names))


def build_identifiers(
    methods: Sequence[str],
    dt: float,
    *,
    options: dict[str, dict[str, Any]] | None = None,
    warm: bool = True,
    **settings: Any,
) -> dict[str, OnlineIdentifier]:
    """Make one online identifier per method, with the given settings.

    Parameters
    ----------
    methods : sequence of str
        Names from :data:`METHOD_NAMES` (see :func:`parse_methods`).
    dt : float
        Sample period in seconds.
    options : dict of str to dict, optional
        Further keyword settings of :func:`~thermolab.ident.online.make_identifier`,
        per method (``{"wlsm": {"form": "standard"}, "srm": {"min_step": 0.5}}``);
        they win over ``settings``.
    warm : bool, optional
        Warm the compiled kernels up before returning (default ``True``; see the
        module notes).
    **settings
        Settings by name (``window=50``, ``gamma=0.7``, ``offset="fit"``), each
        given to every chosen method that takes it (see
        :func:`thermolab.ident.registry.owners`); ``None`` means "not given",
        so the registry's default applies.

    Returns
    -------
    dict of str to OnlineIdentifier
        Keyed by method name, in the order given.

    Raises
    ------
    InvalidParameterError
        For an unknown method or setting, a setting out of range, or a setting
        that none of the chosen methods uses.

    Examples
    --------
    >>> idents = build_identifiers(["srm", "wlsm"], 1.0, gamma=0.7, warm=False)
    >>> list(idents), idents["wlsm"].params["gamma"], idents["wlsm"].params["pmax"]
    (['srm', 'wlsm'], 0.7, 10000.0)
    >>> build_identifiers(["srm"], 1.0, window=50)
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: window is a setting of malsm, which is not among ...
    """
    chosen = parse_methods(methods)
    given = {name: value for name, value in settings.items() if value is not None}
    for name in given:
        takers = owners(name)
        if not takers:
            raise InvalidParameterError(
                f"unknown setting {name!r}; the methods take: {', '.join(SETTINGS)}"
            )
        if not set(takers) & set(chosen):
            raise InvalidParameterError(
                f"{name} is a setting of {', '.join(takers)}, which "
                f"{'is' if len(takers) == 1 else 'are'} not among the methods "
                f"({', '.join(chosen)})"
            )
    extra = dict(options or {})
    stray = sorted(set(extra) - set(chosen))
    if stray:
        raise InvalidParameterError(
            f"options given for {', '.join(stray)}, which is not among the methods "
            f"({', '.join(chosen)})"
        )
    identifiers: dict[str, OnlineIdentifier] = {}
    for method in chosen:
        params = {name: value for name, value in given.items() if method in owners(name)}
        params.update(extra.get(method, {}))
        identifiers[method] = make_identifier(method, dt, **params)
    if warm:
        warm_up(identifiers.values())
    return identifiers


def warm_up(identifiers: Iterable[OnlineIdentifier]) -> None:
    """Run fresh copies of ``identifiers`` over a short synthetic record.

    The copies (same method, period and settings) load or compile every kernel
    the real ones will call; the identifiers given are not touched.

    Parameters
    ----------
    identifiers : iterable of OnlineIdentifier
        Identifiers about to be used in a real-time run.
    """
    for ident in identifiers:
        params = dict(ident.params)
        copy = make_identifier(ident.method, ident.dt, **params)
        # Long enough to fill a window or block and take the solving path;
        # a square wave through a first-order lag excites both parameters.
        n = max(int(params.get("window", 0)), int(params.get("block", 0)), 20) + 5
        a = math.exp(-1.0 / 20.0)
        y = 0.0
        for k in range(n):
            u = 1.0 if (k // 4) % 2 else 0.0
            copy.update(u, y)
            y = a * y + (1.0 - a) * u
        copy.finish()


def warm_up_every_method(dt: float = 1.0) -> tuple[str, ...]:
    """Load (or compile) the kernels of every method, with its default settings.

    A lab server calls it once, in a thread of its own, as it starts: the first
    START after a restart then finds the kernels loaded instead of loading them
    while the student waits (2 s of CPU on an idle machine, past a script's
    10 s HTTP timeout on a loaded one). A START with other settings warms what
    it still needs itself (:func:`build_identifiers`).

    Returns
    -------
    tuple of str
        The methods warmed, in :data:`METHOD_NAMES`' order.

    Examples
    --------
    >>> warm_up_every_method() == METHOD_NAMES
    True
    """
    warm_up(build_identifiers(METHOD_NAMES, dt, warm=False).values())
    return tuple(METHOD_NAMES)
