"""A watcher who joins a long run is told the charts show only its last part.

The lab sends a page that joins mid-run the run's stored samples, capped at
``live_replay_samples``: the first sample, a ``truncated`` notice, the newest
(docs/live-protocol.md, "Replay"). The page must say so plainly and offer the
whole record (the run's CSV); a page that saw the run live from its start has
nothing missing and says nothing. A real lab (its twin sped up), real sockets,
a real browser.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytestmark = pytest.mark.browser

#: The most stored samples one socket is replayed: small, so a run passes it in seconds.
LIMIT = 300
CONFIG = f"""\
title = "ThermoLab replay notice"

[access]
live_replay_samples = {LIMIT}

[[rigs]]
id = "twin"
title = "Digital twin of the paper's box"
spec = "sim"
"""
NOTICE = "[data-testid=chart-truncated]"
OUTPUT = "figure[aria-label='Output y and model prediction against time']"


@pytest.fixture(scope="module")
def replay_lab(tmp_path_factory: pytest.TempPathFactory, start_lab: Any) -> Iterator[Any]:
    users = {"olga": "student", "walt": "student", "vera": "student"}
    with start_lab(tmp_path_factory.mktemp("replay"), users, config=CONFIG) as server:
        yield server


def rig_page(context_for: Any, lab: Any, user: str) -> tuple[Any, Any, list[str]]:
    context = context_for(lab, user, viewport={"width": 1280, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(f"{lab.url}/#/rig/twin")
    page.wait_for_selector(OUTPUT)
    return context, page, errors


def points(page: Any) -> int:
    page.evaluate("() => new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)))")
    return int(page.get_attribute(OUTPUT, "data-points") or 0)


def test_a_watcher_joining_a_long_run_is_told_the_chart_shows_its_last_part(
    replay_lab: Any, context_for: Any
) -> None:
    contexts = []
    try:
        # Walt watches from before the run: he will see every sample live.
        early_ctx, early, early_errors = rig_page(context_for, replay_lab, "walt")
        contexts.append(early_ctx)
        owner_ctx = context_for(replay_lab, "olga")
        contexts.append(owner_ctx)
        owner = owner_ctx.new_page()
        # Her rig page keeps her turn (its heartbeats): a watcher may read the run's
        # record only while it goes.
        owner.goto(f"{replay_lab.url}/#/rig/twin")
        started = owner.evaluate(
            """async () => {
              const c = await fetch('/api/rigs/twin/control', {method: 'POST'});
              const r = await fetch('/api/rigs/twin/runs', {method: 'POST',
                headers: {'Content-Type': 'application/json'},
                body: JSON.stringify({dt: 1, samples: 20000, signal: 'square:4:6:0.1',
                                      methods: ['lsm']})});
              return {control: c.status, status: r.status, body: await r.json()};
            }"""
        )
        assert started["status"] == 201, started
        run_id = started["body"]["id"]
        stored = "async (id) => (await (await fetch(`/api/runs/${id}`)).json()).samplesStored"
        deadline = time.monotonic() + 60
        while owner.evaluate(stored, run_id) < 3 * LIMIT:
            assert time.monotonic() < deadline, "the run did not store its samples"
            owner.wait_for_timeout(100)

        # Vera joins now: the lab replays the first sample and the newest LIMIT - 1.
        late_ctx, late, late_errors = rig_page(context_for, replay_lab, "vera")
        contexts.append(late_ctx)
        late.wait_for_selector(f"{NOTICE}:not([hidden])")
        text = late.inner_text(NOTICE)
        assert f"Run {run_id} is too long to replay here whole" in text
        assert "the charts show only its last part" in text
        found = re.search(r"from sample (\d+) on \(at most (\d+) samples", text)
        assert found is not None, text
        first_after_gap, limit = int(found[1]), int(found[2])
        assert limit == LIMIT
        assert first_after_gap >= 2 * LIMIT  # the middle of the run was skipped
        # The offer: the run's whole record, which Vera may read while the run goes.
        link = late.locator("[data-testid=chart-truncated-csv]")
        assert link.inner_text() == "Download the whole run (CSV)"
        href = link.get_attribute("href")
        assert href == f"/api/runs/{run_id}/samples.csv"
        csv = late.evaluate(
            """async (href) => { const r = await fetch(href);
                                 return {status: r.status, text: await r.text()}; }""",
            href,
        )
        assert csv["status"] == 200
        rows = [line for line in csv["text"].splitlines() if line and line[0].isdigit()]
        assert rows[0].split(",")[0] in ("0", "0.0")  # from the run's first sample on
        assert len(rows) > first_after_gap + LIMIT - 2  # everything the chart lacks, and more
        # The chart does show the run (its newest samples).
        late.wait_for_function(
            "(sel) => Number(document.querySelector(sel)?.dataset.points) > 0", arg=OUTPUT
        )

        # Walt saw the run from its first sample: nothing was skipped, nothing to say.
        assert points(early) > 0
        assert early.locator(NOTICE).is_hidden()
        # END the run, if it has not ended already (a loaded machine's 20000 samples).
        stopped = owner.evaluate(
            "async () => (await fetch('/api/rigs/twin/runs/current/stop', {method: 'POST'})).status"
        )
        assert stopped in (200, 409), stopped
        assert early_errors == []
        assert late_errors == []
    finally:
        for context in contexts:
            context.close()
