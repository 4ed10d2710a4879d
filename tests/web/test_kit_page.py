"""The rig page of a kit's two-heater twin (``sim:kit``): heater 2 and sensor 2 (issue #22, item 1).

A Brazilian student at the controls sees T2 (°C) and Q2 (%) in the "Now"
card and a trace of each on the live charts, beside y and u; she sets Q2 to
40 % from the page during a run, sees it applied, recorded in the run's CSV
and warming sensor 2 at the lab's speed-up; a value out of range is refused
in words before anything is sent. The Q2 field follows the rig's level (back
to 0 when the run ends), but not while she is typing in it. The closed-loop
panel writes degrees as °C, as the readout does. A watcher sees the same
numbers and a locked control, and the page has no English word. Panel 1
lets her choose the pair it identifies (heater 2 → sensor 2); a one-heater
rig's panels have no such choice.
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
from test_messages import catalogue
from test_no_english import reader

pytestmark = pytest.mark.browser

RIG = "kit"
CONFIG = f"""\
title = "Laboratório de controle"

[[rigs]]
id = "{RIG}"
title = "Kit de duas resistências"
spec = "sim:kit"

[[rigs]]
id = "paper"
title = "Gêmeo do artigo"
spec = "sim"
"""
USERS = {"ana": "student", "ben": "student"}
ROLE = "[data-testid=access-role]"
FIELD = "#channel-q2"
SET = "button[data-action=set-channel][data-channel=q2]"
#: The readout's number for a channel, as a JavaScript number (the page writes a decimal comma).
READ = """name => {
  const text = document.querySelector(`[data-readout=${name}]`)?.textContent ?? '–';
  return text === '–' ? null : Number(text.replace(',', '.').replace('−', '-'));
}"""
#: The label of a readout row.
LABEL = """name =>
  document.querySelector(`[data-readout=${name}]`).previousElementSibling.textContent"""
#: The names of an output or input chart's traces, and whether each has a number drawn last.
TRACES = """index => {
  const chart = document.querySelectorAll('.live-charts figure.chart')[index];
  const names = [...chart.querySelectorAll('thead th')].map((th) => th.textContent);
  chart.querySelector('[data-action=chart-table]').click();
  const last = [...chart.querySelectorAll('tbody tr:last-child td')].map((td) => td.textContent);
  chart.querySelector('[data-action=chart-table]').click();
  return { names, last };
}"""
CALL = """async ([method, path, body]) => {
  const r = await fetch(path, {method, headers: {'Content-Type': 'application/json'},
                               body: body === null ? undefined : JSON.stringify(body)});
  return [r.status, method === 'GET' && path.endsWith('.csv') ? await r.text() : await r.json()];
}"""


@pytest.fixture(scope="module")
def kit_lab(
    start_lab: Any, tmp_path_factory: pytest.TempPathFactory, browser: Any
) -> Iterator[Any]:
    with start_lab(tmp_path_factory.mktemp("kit-page"), USERS, config=CONFIG) as server:
        yield server


def test_heater_2_and_sensor_2_on_the_rig_page(
    context_for: Any, kit_lab: Any, artifacts: Path
) -> None:
    words = catalogue("pt-BR")
    ana = reader(context_for, kit_lab, "ana")
    ben = reader(context_for, kit_lab, "ben")
    try:
        page, watcher = ana.page, ben.page
        for pg in (page, watcher):
            pg.goto(f"{kit_lab.url}/#/rig/{RIG}")
            pg.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
        page.click("button[data-action=ask]")
        page.wait_for_function(
            "sel => document.querySelector(sel)?.dataset.role === 'controller'", arg=ROLE
        )
        # The rig's further input and output, in the units it declares them in.
        page.wait_for_function(f"() => ({READ})('t2') > 0")
        assert page.evaluate(LABEL, "t2") == f"{words['channel.t2']} (°C)"
        assert page.evaluate(LABEL, "q2") == f"{words['channel.q2']} (%)"
        assert page.evaluate(READ, "q2") == 0
        assert page.evaluate(LABEL, "y").endswith("(°C)")  # sensor 1 too, not "degC"
        # The closed-loop panel's ranges, labels and axes say °C too.
        page.wait_for_selector("#loop-setpoint-range")
        assert page.inner_text("#loop-setpoint-range").endswith(" °C")
        assert page.inner_text("#loop-kp-range").endswith(" %/°C")
        loop_words = page.evaluate(
            "() => document.querySelector('[data-testid=closed-loop]').textContent"
        )
        assert "degC" not in loop_words
        # The watcher reads them and cannot set heater 2.
        watcher.wait_for_function(f"() => ({READ})('t2') > 0")
        assert watcher.evaluate(LABEL, "t2") == f"{words['channel.t2']} (°C)"
        assert watcher.is_disabled(FIELD)
        assert watcher.is_disabled(SET)
        # A level out of range is refused in words, before anything is sent.
        page.fill(FIELD, "150")
        page.click(SET)
        refusal = page.inner_text("[data-testid=channel-q2-error]")
        assert words["channel.q2"] in refusal
        assert "150" in refusal
        # A run; heater 2 to 40 % from the page, into the run.
        run = {"dt": 1, "samples": 2000, "setpoint": 0, "methods": ["lsm"]}
        status, started = page.evaluate(CALL, ["POST", f"/api/rigs/{RIG}/runs", run])
        assert status == 201, started
        page.wait_for_function(f"() => ({READ})('k') > 5")
        t2_before = page.evaluate(READ, "t2")
        page.fill(FIELD, "40")
        page.click(SET)
        page.wait_for_function(f"() => ({READ})('q2') === 40")
        assert page.inner_text("[data-testid=channel-q2-error]") == ""
        watcher.wait_for_function(f"() => ({READ})('q2') === 40")
        # The watcher's (locked) field follows the rig's level.
        watcher.wait_for_function("sel => document.querySelector(sel).value === '40'", arg=FIELD)
        # Sensor 2 warms (the twin runs 200 times faster than real time).
        page.wait_for_function(f"() => ({READ})('t2') > {t2_before + 2}", timeout=60_000)
        # The charts: T2 beside y, Q2 beside u, each with its number drawn.
        output, heater = page.evaluate(TRACES, 0), page.evaluate(TRACES, 1)
        assert output["names"][-1] == words["channel.t2"], output
        assert heater["names"][-1] == words["channel.q2"], heater
        assert output["last"][-1] != "–", output
        assert heater["last"][-1] == "40", heater
        found = ana.english("the kit's rig page, controller") + ben.english("watcher")
        page.screenshot(path=str(artifacts / "kit-rig-page.png"), full_page=True)
        # A level typed and not sent stays while she is in the field, though the run's
        # end puts heater 2 back at 0; once she leaves it, the field follows the rig.
        page.fill(FIELD, "55")
        status, _ = page.evaluate(CALL, ["POST", f"/api/rigs/{RIG}/runs/current/stop", None])
        assert status == 200
        page.wait_for_function(f"() => ({READ})('q2') === 0")
        assert page.input_value(FIELD) == "55"
        page.locator(FIELD).blur()
        page.wait_for_function("sel => document.querySelector(sel).value === '0'", arg=FIELD)
        watcher.wait_for_function("sel => document.querySelector(sel).value === '0'", arg=FIELD)
        # The run recorded heater 2's step and sensor 2's rise.
        status, text = page.evaluate(CALL, ["GET", f"/api/runs/{started['id']}/samples.csv", None])
        assert status == 200
        rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
        q2 = [float(r["q2"]) for r in rows]
        t2 = [float(r["t2"]) for r in rows]
        on = q2.index(40.0)
        assert set(q2[on:]) == {40.0}
        assert set(q2[:on]) == {0.0}
        assert max(t2[on:]) > t2[on] + 2
        assert found == []
        assert ana.errors == []
        assert ben.errors == []
    finally:
        ana.page.context.close()
        ben.page.context.close()


PAIR = "#srm-lsm-pair"


def test_panel_1_identifies_the_pair_she_chooses(context_for: Any, kit_lab: Any) -> None:
    words = catalogue("pt-BR")
    ana = reader(context_for, kit_lab, "ana")
    ben = reader(context_for, kit_lab, "ben")
    try:
        # Ben watches the kit: his chooser shows the pair of the run going, not his own default.
        ben.page.goto(f"{kit_lab.url}/#/rig/{RIG}")
        ben.page.wait_for_selector(PAIR)
        assert ben.page.input_value(PAIR) == "u>y"
        page = ana.page
        page.goto(f"{kit_lab.url}/#/rig/paper")
        page.wait_for_selector("#srm-lsm-dt")
        page.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
        assert page.locator(PAIR).count() == 0  # one pair: the panels look as before
        page.goto(f"{kit_lab.url}/#/rig/{RIG}")
        page.wait_for_selector(PAIR)
        options = page.eval_on_selector_all(
            f"{PAIR} option", "os => os.map((o) => [o.value, o.textContent])"
        )
        pair = words["panel.pairOption"]
        assert options == [
            ["u>y", pair.format(input=words["channel.q1"], output=words["channel.t1"])],
            ["u>t2", pair.format(input=words["channel.q1"], output=words["channel.t2"])],
            ["q2>y", pair.format(input=words["channel.q2"], output=words["channel.t1"])],
            ["q2>t2", pair.format(input=words["channel.q2"], output=words["channel.t2"])],
        ]
        assert page.input_value(PAIR) == "u>y"  # the first pair by default
        assert page.inner_text(f"label[for='{PAIR[1:]}']") == words["panel.pair"]
        page.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
        if page.get_attribute(ROLE, "data-role") != "controller":  # alone, or after the test above
            page.click("button[data-action=ask]")
        page.wait_for_function(
            "sel => document.querySelector(sel)?.dataset.role === 'controller'", arg=ROLE
        )
        page.select_option(PAIR, "q2>t2")
        page.fill("#srm-lsm-dt", "2")
        page.fill("#srm-lsm-n", "300")
        page.fill("#srm-lsm-setpoint", "50")
        page.click("[data-panel-view=srm-lsm] button[data-action=start]")
        # The run identifies heater 2 -> sensor 2 (the twin runs its 600 s in seconds).
        deadline = time.monotonic() + 60
        while True:
            status, runs = page.evaluate(CALL, ["GET", f"/api/runs?rig={RIG}", None])
            assert status == 200, runs
            run = runs[0] if runs else None  # newest first: hers, once START is in
            if run and run["settings"]["input"] != "u" and run["status"] != "running":
                break
            assert time.monotonic() < deadline, run
            page.wait_for_timeout(500)
        assert (run["settings"]["input"], run["settings"]["output"]) == ("q2", "t2"), run
        assert run["status"] == "finished", run
        assert run["settings"]["setpoint"] == 50
        ben.page.wait_for_function("sel => document.querySelector(sel).value === 'q2>t2'", arg=PAIR)
        # Panel 1 says which pair its model is of, and shows the model.
        used = words["panel.pairUsed"].format(
            pair=pair.format(input=words["channel.q2"], output=words["channel.t2"])
        )
        page.wait_for_function(
            """([sel, text]) => document.querySelector(sel)?.textContent.includes(text)""",
            arg=["[data-testid=operating-point-srm-lsm]", used],
        )
        page.wait_for_function(
            """sel => !['', '–'].includes(document.querySelector(sel)?.textContent ?? '')""",
            arg="[data-panel-view=srm-lsm] tr[data-method=lsm] td[data-field=K]",
        )
        # The charts draw the model of heater 2 -> sensor 2 over T2 (not over y, from u).
        page.wait_for_selector("#overlay-method option[value=lsm]", state="attached")
        page.select_option("#overlay-method", "lsm")
        output = page.evaluate(TRACES, 0)
        model_at = output["names"].index(words["series.model"])
        t2_at = output["names"].index(words["channel.t2"])
        last = [float(v.replace(",", ".").replace("−", "-")) for v in output["last"]]
        assert abs(last[model_at] - last[t2_at]) < 2.0, output
        # The run's page says the pair and draws Q2, T2 and the model of them.
        page.goto(f"{kit_lab.url}/#/runs/{run['id']}")
        page.wait_for_selector("#run-model")
        facts = page.inner_text("dl.facts")
        assert words["panel.pair"] in facts
        assert pair.format(input=words["channel.q2"], output=words["channel.t2"]) in facts
        assert "input" not in facts  # the setting is said as the pair, not by its name
        run_traces = TRACES.replace(".live-charts figure.chart", "main figure.chart")
        output, heater = page.evaluate(run_traces, 0), page.evaluate(run_traces, 1)
        assert output["names"][1:] == [words["channel.t2"], words["series.model"]], output
        assert heater["names"][1:] == [words["channel.q2"]], heater
        assert heater["last"][-1] == "50", heater
        last = [float(v.replace(",", ".").replace("−", "-")) for v in output["last"]]
        assert abs(last[1] - last[2]) < 2.0, output
        assert ana.english("the pair chooser") == []
        assert ana.errors == []
        assert ben.errors == []
    finally:
        ana.page.context.close()
        ben.page.context.close()
