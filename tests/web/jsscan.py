"""A small scanner of the interface's JavaScript: its string literals, with context.

Used by the message-catalogue tests: it finds every string and template literal
(the static parts of a template, its ``${…}`` parts replaced by ``{}``) outside
comments and regular expressions, with the code just before it, so a test can
tell a catalogue key or an attribute value from text a user would read. Written
by hand: the tests need only this much of JavaScript's grammar, and a full
parser would be a new dependency for the test suite.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Characters after which a ``/`` starts a regular expression, not a division.
_REGEX_BEFORE = set("(,=:[!&|?{};+-*%<>~^") | {""}


@dataclass(frozen=True)
class Literal:
    """One string literal: its text, the code before it and its line."""

    text: str
    before: str
    line: int


def literals(source: str) -> list[Literal]:
    """Every string literal of ``source`` in order (template parts joined by ``{}``).

    >>> [x.text for x in literals('a("x y", `Run ${id} of ${n ? `${n}` : ""}`) // "no"')]
    ['x y', '{}', '', 'Run {} of {}']
    """
    found: list[Literal] = []
    _scan(source, 0, found, stop_at_brace=False)
    found.sort(key=lambda x: x.line)
    return found


def _line(source: str, i: int) -> int:
    return source.count("\n", 0, i) + 1


def _scan(src: str, i: int, out: list[Literal], *, stop_at_brace: bool) -> int:
    depth = 0
    prev = ""
    n = len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j == -1 else j
            continue
        if src.startswith("/*", i):
            j = src.find("*/", i + 2)
            i = n if j == -1 else j + 2
            continue
        if c in "\"'":
            j = i + 1
            buf = []
            while j < n and src[j] != c:
                if src[j] == "\\":
                    buf.append(src[j : j + 2])
                    j += 2
                    continue
                buf.append(src[j])
                j += 1
            out.append(Literal("".join(buf), src[max(0, i - 60) : i], _line(src, i)))
            i = j + 1
            prev = c
            continue
        if c == "`":
            start = i
            j = i + 1
            parts: list[str] = []
            buf = []
            while j < n and src[j] != "`":
                if src[j] == "\\":
                    buf.append(src[j : j + 2])
                    j += 2
                elif src.startswith("${", j):
                    buf.append("{}")
                    j = _scan(src, j + 2, out, stop_at_brace=True)
                else:
                    buf.append(src[j])
                    j += 1
            parts.append("".join(buf))
            out.append(Literal("".join(parts), src[max(0, start - 60) : start], _line(src, start)))
            i = j + 1
            prev = "`"
            continue
        if c == "/" and prev in _REGEX_BEFORE:
            j = i + 1
            in_class = False
            while j < n and (in_class or src[j] != "/"):
                if src[j] == "\\":
                    j += 1
                elif src[j] == "[":
                    in_class = True
                elif src[j] == "]":
                    in_class = False
                j += 1
            i = j + 1
            prev = "x"
            continue
        if c == "{":
            depth += 1
        elif c == "}":
            if stop_at_brace and depth == 0:
                return i + 1
            depth -= 1
        if not c.isspace():
            prev = c
            if c.isalnum() or c in "_$)]":
                # A word or a closing bracket: a "/" after it divides. Keywords
                # before a regex (return /x/) do not occur in this code base.
                prev = "x"
        i += 1
    return i
