"""End to end: the "Closed loop" panel tunes a PID from an identified model and steps it.

A student identifies the kit's twin (a heater step, LSM finds the dead time),
opens the tuning table of that run in the fourth panel, picks SIMC (the gains
fill in), starts a closed-loop set-point step on the twin at the lab's
speed-up, and sees the measured overshoot and settling time beside the
predicted ones when the run ends — and they agree, on a box at rest (the
settling times unless the page says an overshoot sits at the band's edge): the
test lets the twin cool back to where the identification began (the
heater is off between runs; at the lab's speed-up that takes seconds)
before it closes the loop, because the prediction starts the model settled
at the run's first output.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.browser

RIG = "twin-loop"
ROLE = "[data-testid=access-role]"
PANEL = "[data-testid=closed-loop]"


def test_tune_from_an_identified_model_and_step_the_set_point(
    logged_in: Any, lab: Any, artifacts: Path
) -> None:
    context = logged_in("pia", viewport={"width": 1280, "height": 900})
    try:
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(f"{lab.url}/#/rig/{RIG}")
        page.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
        page.click("button[data-action=ask]")
        page.wait_for_function(
            "sel => document.querySelector(sel)?.dataset.role === 'controller'", arg=ROLE
        )
        # Identify: a 50 % heater step, LSM (which searches the dead time).
        answer = page.evaluate(
            """async () => {
              const r = await fetch('/api/rigs/twin-loop/runs', {method: 'POST',
                headers: {'Content-Type': 'application/json'},
                body: JSON.stringify({dt: 1, samples: 1200, signal: 'step:0:50@0',
                                      methods: ['lsm']})});
              return {status: r.status, body: await r.json()};
            }"""
        )
        assert answer["status"] == 201, answer
        ident_run = answer["body"]["id"]
        # The identification run ends by itself (1200 samples at the lab's speed-up).
        finished = """async (id) => {
            const run = await (await fetch(`/api/runs/${id}`)).json();
            return run.status === 'finished';
        }"""
        deadline = time.monotonic() + 90
        while not page.evaluate(finished, ident_run):
            assert time.monotonic() < deadline, "the identification run did not end"
            page.wait_for_timeout(250)
        # The box is warm and cooling; wait until it is back at its starting output
        # (within the sensor's quantum, 0.32 degC) so the loop closes on a box at rest.
        ambient = page.evaluate(
            """async (id) => (await (await fetch(`/api/runs/${id}/export.json`)).json())
                .samples.y[0]""",
            ident_run,
        )
        reading = """async () =>
            (await (await fetch('/api/rigs/twin-loop/reading')).json()).y"""
        deadline = time.monotonic() + 60
        while abs(page.evaluate(reading) - ambient) > 0.33:
            assert time.monotonic() < deadline, "the twin did not cool back to rest"
            page.wait_for_timeout(250)
        # The tuning table of that run; SIMC fills in the gains.
        panel = page.locator(PANEL)
        panel.scroll_into_view_if_needed()
        page.fill("#loop-modelRun", str(ident_run))
        page.click("button[data-action=tuning]")
        page.wait_for_selector("[data-testid=tuning-table] table")
        rows = page.locator("[data-testid=tuning-table] tbody tr")
        assert rows.count() == 7
        page.click("button[data-action=use][data-rule=simc-pi]")
        assert page.input_value("#loop-kp") != ""
        assert page.input_value("#loop-ti") != ""
        page.fill("#loop-setpoint", "45")
        page.fill("#loop-samples", "900")
        page.click("button[data-action=loop-start]")
        page.wait_for_selector("[data-testid=loop-status]:has-text('45')", timeout=30_000)
        # The run ends by itself; the measured figures appear beside the predicted ones.
        page.wait_for_selector("[data-figure='loop.measured-overshoot']", timeout=90_000)
        figures = {
            (who, what): _number(page.inner_text(f"[data-figure='loop.{who}-{what}']"))
            for who in ("measured", "predicted")
            for what in ("settling", "iae")
        }
        note = page.locator("[data-testid=loop-note]")
        note_text = note.inner_text() if note.count() else ""
        # The twin is the kit's two nodes with a quantised sensor, the model LSM's FOPDT
        # fit of it: on a box at rest the IAEs agree within 15 %, and so do the 2 %
        # settling times unless an overshoot sits at the band's edge (LSM's dead time
        # varies by a sample or two with the noise, and with it the tuned peak), where
        # the settling time jumps and the page says to compare the IAE instead.
        m_iae, p_iae = figures["measured", "iae"], figures["predicted", "iae"]
        assert abs(m_iae - p_iae) <= 0.15 * m_iae, (figures, note_text)
        m, p = figures["measured", "settling"], figures["predicted", "settling"]
        assert m > 0
        assert p > 0
        if "settling band" not in note_text:
            assert abs(m - p) <= 0.15 * m, (figures, note_text)
        panel.screenshot(path=str(artifacts / "closed-loop.png"))
        page.click("button[data-action=release]")
        assert errors == []
    finally:
        context.close()


def _number(text: str) -> float:
    """A figure as the page writes it in English (this browser's language): 1,331 or 1\u202f331."""
    assert text not in ("", "\u2013"), "a figure is missing"
    return float(text.replace("\u202f", "").replace(",", "").replace(" ", ""))
