"""Command-line options generated from the method registry.

Each :class:`~thermolab.ident.registry.Setting` becomes one option: its flag
(``--name``, underscores as dashes), value parser, metavar, help text and
default all come from the declaration, so ``thermolab identify`` and
``thermolab run`` cannot drift from the library. The options default to
``None`` ("not given"): the library then applies the registry's default, and
an option given for a method that does not take it can be refused by name.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from thermolab.cli._words import _, library_text
from thermolab.ident.registry import METHODS, Setting

__all__ = ["add_setting_options", "given_settings", "option", "settings_of"]


def option(setting: Setting) -> str:
    """The flag of ``setting``: ``--recompute-every`` for ``recompute_every``."""
    return "--" + setting.name.replace("_", "-")


def settings_of(methods: Sequence[str] | None = None) -> tuple[Setting, ...]:
    """The settings of ``methods`` (default: all), each once, in the registry's order."""
    seen: dict[str, Setting] = {}
    for m in METHODS:
        if methods is None or m.name in methods:
            for s in m.settings:
                seen.setdefault(s.name, s)
    return tuple(seen.values())


def add_setting_options(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, settings: Iterable[Setting]
) -> None:
    """Add one option per setting, with the registry's parser, help and default."""
    for s in settings:
        takers = [m.name for m in METHODS if s in m.settings]
        shown = _shown_default(s)
        where = ", ".join(takers) if len(takers) < len(METHODS) - 1 else _("all but srm")
        help_text = f"{where}: {library_text(s.help)}"
        if shown:
            help_text += " " + _("(default {default})").format(default=shown)
        kwargs: dict[str, Any] = {"dest": s.name, "default": None, "help": help_text}
        if s.type == "choice":
            kwargs["choices"] = s.choices
        else:
            kwargs["type"] = _parser_for(s)
            kwargs["metavar"] = s.metavar or s.name.upper()
        # argparse formats help with %; a literal percent sign must be doubled.
        kwargs["help"] = kwargs["help"].replace("%", "%%")
        parser.add_argument(option(s), **kwargs)


def given_settings(args: argparse.Namespace, settings: Iterable[Setting]) -> dict[str, Any]:
    """``{name: value}`` of the settings given on the command line."""
    return {s.name: getattr(args, s.name) for s in settings if getattr(args, s.name) is not None}


def _shown_default(s: Setting) -> str:
    d = s.default
    if d is None:
        return ""
    if isinstance(d, tuple):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in d)
    if isinstance(d, float):
        return f"{d:g}"
    return str(d)


def _parser_for(s: Setting) -> Callable[[str], Any]:
    flag = option(s)

    def refuse(text: str) -> argparse.ArgumentTypeError:
        return argparse.ArgumentTypeError(
            _("{option} must be {allowed}, got {value}").format(
                option=flag, allowed=library_text(s.allowed()), value=repr(text)
            )
        )

    def number(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise refuse(text) from None
        if not s.in_range(v):
            raise refuse(text)
        return v

    def integer(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise refuse(text) from None
        if not s.in_range(v):
            raise refuse(text)
        return v

    def number_list(text: str) -> list[float]:
        return [number(part.strip()) for part in text.split(",")]

    def arx_order(text: str) -> tuple[int, int, int]:
        parts = [p.strip() for p in text.split(",")]
        try:
            na, nb, delay = (int(p) for p in parts)
        except ValueError:
            raise argparse.ArgumentTypeError(
                _(
                    "{option} must be three whole numbers NA,NB,DELAY (e.g. 1,1,0), got {value}"
                ).format(option=flag, value=repr(text))
            ) from None
        return na, nb, delay

    def offset(text: str) -> str | float:
        if text in s.choices:
            return text
        try:
            v = float(text)
        except ValueError:
            raise refuse(text) from None
        if not math.isfinite(v):
            raise refuse(text)
        return v

    parsers: dict[str, Callable[[str], Any]] = {
        "number": number,
        "covariance": number,
        "integer": integer,
        "number_list": number_list,
        "arx_order": arx_order,
        "offset": offset,
    }
    return parsers[s.type]
