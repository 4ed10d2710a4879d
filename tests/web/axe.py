"""axe-core in the browser tests: inject the npm package's axe.min.js and run it on a page.

axe-core is an npm devDependency (package.json); without node_modules/axe-core
the checks skip, saying why. The contexts that run it bypass the lab's
Content-Security-Policy, which (rightly) refuses an injected script.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

AXE = Path(__file__).parents[2] / "node_modules" / "axe-core" / "axe.min.js"
BLOCKING = ("serious", "critical")


def axe_skip_reason() -> str | None:
    """Why the axe checks cannot run here (None: they can)."""
    if not AXE.is_file():
        return f"axe-core is not installed ({AXE} missing): run npm ci"
    return None


def serious_violations(page: Any) -> list[str]:
    """Every serious or critical axe violation on the page, one line each (rule: targets)."""
    reason = axe_skip_reason()
    if reason is not None:
        pytest.skip(reason)
    if not page.evaluate("() => typeof window.axe === 'object'"):
        page.add_script_tag(content=AXE.read_text(encoding="utf-8"))
    result = page.evaluate(
        """async () => {
          const r = await axe.run(document);
          return { passes: r.passes.length, violations: r.violations.map((v) => ({
            id: v.id, impact: v.impact,
            targets: v.nodes.slice(0, 5).map((n) => n.target.join(' ')) })) };
        }"""
    )
    assert result["passes"] > 10, "axe ran no rules: the page was not checked"
    return [
        f"{v['id']} ({v['impact']}): {', '.join(v['targets'])}"
        for v in result["violations"]
        if v["impact"] in BLOCKING
    ]
