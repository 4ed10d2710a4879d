"""The closed-loop panel chooses the kit's heater it controls (issue #22, item 3).

On the kit's twin (``sim:kit``) the fourth panel offers a chooser of the
heater the PID drives, in the reader's words; a Brazilian student picks heater
2, starts the loop, sees the panel's chart follow sensor 2, and steps heater 1
by hand from the panel as a disturbance; the run's loop is on q2/t2 and its
record has heater 1's step. On the paper's one-heater box the panel has no
chooser at all (it looks as before).
"""

from __future__ import annotations

import csv
import io
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_kit_page import CALL, READ, ROLE
from test_messages import catalogue
from test_no_english import reader

pytestmark = pytest.mark.browser

CONFIG = """\
title = "Laboratório de controle"

[[rigs]]
id = "kit"
title = "Kit de duas resistências"
spec = "sim:kit"

[[rigs]]
id = "box"
title = "Caixa do artigo"
spec = "sim"
"""
USERS = {"ana": "student"}
CHOOSER = "#loop-heater"


@pytest.fixture(scope="module")
def loop_lab(
    start_lab: Any, tmp_path_factory: pytest.TempPathFactory, browser: Any
) -> Iterator[Any]:
    with start_lab(tmp_path_factory.mktemp("kit-loop-page"), USERS, config=CONFIG) as server:
        yield server


def _open(page: Any, url: str, rig: str) -> None:
    page.goto(f"{url}/#/rig/{rig}")
    page.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
    page.wait_for_selector("#loop-setpoint")


def _at_the_controls(page: Any) -> None:
    """Ask for the rig's controls, unless already holding them (after the test before)."""
    if page.get_attribute(ROLE, "data-role") != "controller":
        page.click("button[data-action=ask]")
    page.wait_for_function(
        "sel => document.querySelector(sel)?.dataset.role === 'controller'", arg=ROLE
    )


def test_the_panel_chooses_heater_2_and_heater_1_disturbs_it(
    context_for: Any, loop_lab: Any, artifacts: Path
) -> None:
    words = catalogue("pt-BR")
    ana = reader(context_for, loop_lab, "ana")
    page = ana.page
    try:
        # The one-heater box: no chooser, no disturbance heater; the panel as before.
        _open(page, loop_lab.url, "box")
        assert page.locator(CHOOSER).count() == 0
        assert page.locator("#loop-other").count() == 0
        assert page.locator("label[for=loop-u]").inner_text() == words["loop.manualInput"]
        # The kit: both pairs, in the reader's words, the run's own first.
        _open(page, loop_lab.url, "kit")
        _at_the_controls(page)
        options = page.eval_on_selector_all(
            f"{CHOOSER} option", "os => os.map((o) => [o.value, o.textContent])"
        )
        pair = words["loop.pair"].format(heater=words["channel.q2"], sensor=words["channel.t2"])
        assert options == [["u", words["loop.pairOwn"]], ["q2", pair]]
        assert page.locator("label[for=loop-heater]").inner_text() == words["loop.heater"]
        page.select_option(CHOOSER, "q2")
        # The manual field is then heater 1's level at the start, a disturbance.
        assert page.locator("label[for=loop-u]").inner_text() == words["loop.otherStart"]
        page.fill("#loop-kp", "5")
        page.fill("#loop-ti", "150")
        page.fill("#loop-setpoint", "40")
        page.fill("#loop-u", "0")
        page.fill("#loop-dt", "2")
        page.fill("#loop-samples", "900")
        page.click("button[data-action=loop-start]")
        page.wait_for_selector("[data-testid=loop-status]:has-text('40')", timeout=30_000)
        status, rig = page.evaluate(CALL, ["GET", "/api/rigs/kit/loop", None])
        assert status == 200
        assert (rig["loop"]["heater"], rig["loop"]["sensor"]) == ("q2", "t2")
        run_id = rig["loop"]["run"]
        # Heater 2 is the PID's: its field in the "Further inputs" card is disabled and
        # says why; the lab refuses a hand setting all the same, in the reader's words.
        page.wait_for_function("() => document.querySelector('#channel-q2').disabled")
        assert page.is_disabled("button[data-action=set-channel][data-channel=q2]")
        assert page.inner_text("[data-testid=channel-q2-driven]") == words["furtherInputs.driven"]
        status, refused = page.evaluate(CALL, ["PUT", "/api/rigs/kit/channels/q2", {"level": 10}])
        assert (status, refused["code"]) == (409, "channel_in_loop")
        assert refused["message"] == words["error.channel_in_loop"]
        # A page opened during the run says the same.
        again = page.context.new_page()
        again.goto(f"{loop_lab.url}/#/rig/kit")
        again.wait_for_function("() => document.querySelector('#channel-q2')?.disabled")
        again.close()
        # The PID warms sensor 2 towards 40 °C; then heater 1 is stepped from the panel.
        page.wait_for_function(f"() => ({READ})('t2') > 35", timeout=60_000)
        assert page.is_visible("#loop-other")
        assert page.locator("label[for=loop-other]").inner_text() == words["loop.otherHeater"]
        page.fill("#loop-other", "60")
        page.click("button[data-action=loop-other]")
        page.wait_for_function(f"() => ({READ})('u') === 60")
        assert page.inner_text("[data-testid=loop-error]") == ""
        # The panel's chart draws sensor 2 (near 40 °C), not sensor 1.
        drawn = page.evaluate(
            """() => {
              const chart = document.querySelector('[data-testid=closed-loop] figure.chart');
              chart.querySelector('[data-action=chart-table]').click();
              const cells = [...chart.querySelectorAll('tbody tr:last-child td')];
              return cells.map((td) => td.textContent);
            }"""
        )
        y_drawn = float(drawn[2].replace(",", ".").replace("−", "-"))
        assert 35.0 < y_drawn < 45.0, drawn
        page.locator("[data-testid=closed-loop]").screenshot(
            path=str(artifacts / "kit-loop-heater-2.png")
        )
        found = ana.english("the kit's closed-loop panel on heater 2")
        status, _ = page.evaluate(CALL, ["POST", "/api/rigs/kit/runs/current/stop", None])
        assert status == 200
        page.wait_for_function(f"() => ({READ})('q2') === 0")
        assert not page.is_disabled("#channel-q2")  # the hand's again once the run ends
        status, text = page.evaluate(CALL, ["GET", f"/api/runs/{run_id}/samples.csv", None])
        rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
        u = [float(r["u"]) for r in rows]
        assert 60.0 in u
        assert u[0] == 0.0
        assert max(float(r["q2"]) for r in rows) > 30.0
        assert found == []
        assert ana.errors == []
    finally:
        page.context.close()


def test_the_tuning_table_of_a_heater_2_model_tunes_heater_2s_loop_only(
    context_for: Any, loop_lab: Any
) -> None:
    words = catalogue("pt-BR")
    ana = reader(context_for, loop_lab, "ana")
    page = ana.page
    try:
        _open(page, loop_lab.url, "kit")
        _at_the_controls(page)
        # A model of heater 2 -> sensor 2, identified by an open-loop run of that pair.
        body = {"dt": 2.0, "samples": 400, "signal": "step:0:50@10", "methods": ["lsm"],
                "input": "q2", "output": "t2"}  # fmt: skip
        status, run = page.evaluate(CALL, ["POST", "/api/rigs/kit/runs", body])
        assert status == 201, run
        deadline = time.monotonic() + 60
        while (shown := page.evaluate(CALL, ["GET", f"/api/runs/{run['id']}", None])[1])[
            "status"
        ] == "running":
            assert time.monotonic() < deadline, shown
            page.wait_for_timeout(300)
        assert shown["status"] == "finished", shown
        # The table for heater 2's loop says which pair its model is of, in her words.
        page.select_option(CHOOSER, "q2")
        page.fill("#loop-modelRun", str(run["id"]))
        page.click("button[data-action=tuning]")
        page.wait_for_selector("[data-testid=tuning-table] table")
        said = words["loop.modelPair"].format(input=words["channel.q2"], output=words["channel.t2"])
        assert page.inner_text("[data-testid=tuning-pair]") == said
        assert page.locator("[data-testid=tuning-table] button[data-action=use]").count() > 0
        assert page.inner_text("[data-testid=loop-error]") == ""
        # Heater 1's loop refuses that model, and says why.
        page.select_option(CHOOSER, "u")
        page.click("button[data-action=tuning]")
        page.wait_for_function(
            "([sel, text]) => document.querySelector(sel)?.textContent === text",
            arg=["[data-testid=loop-error]", words["error.model_pair_mismatch"]],
        )
        assert ana.english("the tuning table of heater 2's model") == []
        assert ana.errors == []
    finally:
        page.context.close()
