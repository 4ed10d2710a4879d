"""The command line's closed-loop examples print what the guide shows (issue #24).

``docs/command-line.md``'s "Close the loop" section shows ``thermolab run``
commands, each followed by lines of its output as ``# ...`` comments. Every
command runs here, as ``.venv/bin/thermolab`` would run it (in a temporary
folder, for the CSV it writes), and every shown line must be a line of its
output, in order, spaces aside (a line ending in ``...`` is the start of one).
The commands seed the twins' noise, so the figures are the same at every run on
one machine; across machines the output-error optimiser's last digits move (a
CI machine printed 0.587139 where the guide, written on another, shows
0.587138), so figures agree to 1e-5 relative and the words exactly.
"""

from __future__ import annotations

import math
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

PAGE = Path(__file__).resolve().parents[2] / "docs" / "command-line.md"
SECTION = "## Close the loop"


def examples() -> list[tuple[str, list[str]]]:
    """The section's commands, each with the output lines shown under it."""
    text = PAGE.read_text(encoding="utf-8")
    section = text[text.index(SECTION) :]
    section = section[: section.index("\n## ", len(SECTION))]
    found: list[tuple[str, list[str]]] = []
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        command: list[str] = []
        for line in block.splitlines():
            if line.startswith(".venv/bin/thermolab") or command:
                command.append(line.rstrip("\\").strip())
                if not line.endswith("\\"):  # the command's last line
                    found.append((" ".join(command), []))
                    command = []
            elif line.startswith("#"):
                found[-1][1].append(line[1:].strip())
    return found


def _spaced(line: str) -> str:
    return " ".join(line.split())


_FIGURE = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _first_words(line: str, like: str) -> str:
    """As many words of ``line`` as ``like`` has."""
    return " ".join(line.split()[: len(like.split())])


def _same(printed: str, shown: str) -> bool:
    """The same words, and figures equal to 1e-5 relative (see the module's docstring)."""
    if _FIGURE.sub("#", printed) != _FIGURE.sub("#", shown):
        return False
    pairs = zip(_FIGURE.findall(printed), _FIGURE.findall(shown), strict=True)
    return all(math.isclose(float(a), float(b), rel_tol=1e-5) for a, b in pairs)


def test_the_section_shows_commands_with_their_output() -> None:
    shown = examples()
    assert len(shown) == 3
    assert all(lines for _, lines in shown)
    # Closed loop identifies with the whole-record methods (the section says why).
    assert all("--method lsm" in command for command, _ in shown[:2])


@pytest.mark.parametrize(
    ("command", "lines"), examples(), ids=lambda v: v[:60] if isinstance(v, str) else ""
)
def test_each_command_prints_the_lines_shown(
    command: str, lines: list[str], tmp_path: Path
) -> None:
    argv = shlex.split(command)
    assert argv[0] == ".venv/bin/thermolab"
    done = subprocess.run(
        [sys.executable, "-m", "thermolab", *argv[1:]],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    printed = [_spaced(line) for line in done.stdout.splitlines()]
    at = 0
    for want in map(_spaced, lines):
        prefix = want.endswith("...")
        stem = want.removesuffix("...").rstrip()
        while at < len(printed) and not (
            _same(_first_words(printed[at], stem), stem) if prefix else _same(printed[at], want)
        ):
            at += 1
        assert at < len(printed), f"not printed (in order): {want!r}\n{done.stdout}"
        at += 1
