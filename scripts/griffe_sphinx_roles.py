"""A griffe extension for the documentation site: Sphinx roles as Markdown code.

ThermoLab's docstrings are numpydoc, written for both ``help()`` and Sphinx,
so they cross-reference with Sphinx roles (``:func:`least_squares```,
``:class:`~thermolab.rigs.Rig```) and end a paragraph before a literal block
with ``::``. mkdocstrings renders docstrings as Markdown, where those would
show as raw text; this extension (named in ``mkdocs.yml``) rewrites each role
to its target's name as code (the last part only after ``~``, as Sphinx shows
it) and ``::`` to ``:``. The source files are not changed.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?[a-z]+:`(~?)([^`<]*?)(?:\s*<([^>`]+)>)?`")
LITERAL_BLOCK = re.compile(r"(\S)::$", re.MULTILINE)


def _role(match: re.Match[str]) -> str:
    tilde, text, target = match.group(1), match.group(2).strip(), match.group(3)
    if target:  # :role:`shown text <target>`
        return f"`{text}`" if text else f"`{target}`"
    name = text.rsplit(".", 1)[-1] if tilde else text.lstrip(".")
    return f"`{name}`"


def markdown_of(text: str) -> str:
    """``text`` with its Sphinx roles as code spans and ``::`` as ``:``.

    >>> markdown_of("See :func:`~thermolab.ident.least_squares` and :mod:`.outbox`::")
    'See `least_squares` and `outbox`:'
    """
    return LITERAL_BLOCK.sub(r"\1:", ROLE.sub(_role, text))


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown_of(obj.docstring.value)
