"""A phone doing the experiment, the charts' data tables, and axe-core on every page.

On 375 x 812 the first screen holds the access card (the role, the time left,
ASK or RELEASE), the output chart, the set point, START/END and the panel's
instruction, for a watcher and for the controller, with no empty notice bar;
the results come right below. Every table fits the screen or scrolls inside
its own box (every column reachable, never the page); the live charts show the
last 100 s or 500 s of a long run on request (finger or keyboard); each chart
can show its newest samples as a table; axe-core finds no serious or critical
violation on any page, in English and in Portuguese.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import LabServer, running_lab

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROLE = "[data-testid=access-role]"
#: How much wider than the screen the page is (> 0: it scrolls sideways).
OVERFLOW = "() => document.documentElement.scrollWidth - window.innerWidth"
MESSAGES = Path(__file__).parents[2] / "src/thermolab/web/static/js/messages"
CONFIG = """\
title = "ThermoLab phones"

[[rigs]]
id = "phone-en"
title = "Phone twin (en)"
spec = "sim"

[[rigs]]
id = "phone-pt"
title = "Phone twin (pt-BR)"
spec = "sim"

[[rigs]]
id = "phone-wide"
title = "Phone twin (tables)"
spec = "sim"
"""
USERS = {"pia": "student", "rui": "student", "ada": "student", "tom": "teacher"}
LOCALES = {"en-US": ("en", "phone-en", "pia"), "pt-BR": ("pt-BR", "phone-pt", "rui")}


def catalogue(language: str) -> dict[str, Any]:
    text = (MESSAGES / f"{language}.js").read_text(encoding="utf-8")
    messages: dict[str, Any] = json.loads(text[text.index("= {") + 2 : text.rindex("}") + 1])
    return messages


@pytest.fixture(scope="module")
def phone_lab(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[LabServer]:
    with running_lab(tmp_path_factory.mktemp("phones"), USERS, config=CONFIG) as server:
        yield server


def log_in(browser: Any, lab: LabServer, user: str, locale: str, **options: Any) -> Any:
    context = browser.new_context(locale=locale, **options)
    page = context.new_page()
    page.goto(f"{lab.url}/")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector("#nav:not([hidden])")
    return page


def boxes(page: Any, selectors: dict[str, str]) -> dict[str, dict[str, float]]:
    found: dict[str, dict[str, float]] = page.evaluate(
        """(selectors) => Object.fromEntries(Object.entries(selectors).map(([name, sel]) => {
             const el = [...document.querySelectorAll(sel)].find((e) => e.offsetParent !== null);
             const r = el ? el.getBoundingClientRect() : null;
             return [name, r && { top: r.top, bottom: r.bottom, left: r.left, right: r.right }];
           }))""",
        selectors,
    )
    return found


def on_first_screen(page: Any, found: dict[str, dict[str, float] | None], *names: str) -> None:
    """Each named box lies whole within the first screen (375 px wide)."""
    height = page.evaluate("() => window.innerHeight")
    for name in names:
        box = found[name]
        assert box is not None, name
        assert box["top"] >= 0, (name, box)
        assert box["bottom"] <= height, (name, box, height)
        assert box["left"] >= 0, (name, box)
        assert box["right"] <= 375, (name, box)


def empty_bars(page: Any) -> list[str]:
    """Notice bars shown with nothing in them (the yellow bar under the title)."""
    found: list[str] = page.evaluate(
        """() => [...document.querySelectorAll(
                 '.notice, .lock-notice, .conn, .time-warning, .error')]
             .filter((e) => e.getBoundingClientRect().height > 0 && !e.textContent.trim())
             .map((e) => e.outerHTML.slice(0, 120))"""
    )
    return found


@pytest.mark.parametrize("locale", sorted(LOCALES))
def test_a_phone_shows_the_chart_the_set_point_and_start_end_together(
    browser: Any, phone_lab: LabServer, locale: str, artifacts: Path
) -> None:
    language, rig, user = LOCALES[locale]
    messages = catalogue(language)
    page = log_in(browser, phone_lab, user, locale, viewport={"width": 375, "height": 812})
    view = "[data-panel-view]:not([hidden])"
    card = {
        "ask": "button[data-action=ask]",
        "release": "button[data-action=release]",
        "role": ROLE,
        "timeLeft": "section.access dd[data-field=timeLeft]",
        "instruction": f"{view} .panel-intro",
    }
    try:
        page.goto(f"{phone_lab.url}/#/rig/{rig}")
        # A watcher: the access card with ASK and the panel's instruction on the first screen.
        page.wait_for_selector(f"{ROLE}[data-role=watcher]")
        page.wait_for_selector(f"{view} .panel-intro")
        found = boxes(page, card)
        on_first_screen(page, found, "ask", "role", "timeLeft", "instruction")
        assert page.text_content(card["instruction"]) == messages["panel.srmLsm.intro"]
        assert empty_bars(page) == []
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        # The role can show (from the rig's live status) before ASK's answer; its
        # handler then moves focus to RELEASE, down the page, which scrolls it.
        page.wait_for_selector("button[data-action=release]:focus")
        parts = {
            "chart": f"figure.chart[aria-label='{messages['charts.output']}'] .chart-plot",
            "setpoint": f"{view} input[name=setpoint-live]",
            "start": f"{view} button[data-action=start]",
            "end": f"{view} button[data-action=end]",
            "results": f"{view} .panel-results",
        }
        # RELEASE is near the top: putting focus on it did not scroll the page away.
        assert page.evaluate("() => window.scrollY") == 0
        found = boxes(page, {**parts, **card})
        height = page.evaluate("() => window.innerHeight")
        on_first_screen(
            page,
            found,
            "chart",
            "setpoint",
            "start",
            "end",
            "release",
            "role",
            "timeLeft",
            "instruction",
        )
        assert page.get_attribute(ROLE, "data-role") == "controller"
        assert empty_bars(page) == []
        # The results come next: right below the set point and START/END.
        assert found["results"]["top"] >= max(found[n]["bottom"] for n in ("setpoint", "end"))
        assert page.evaluate(OVERFLOW) <= 0
        # A run: END becomes usable where it is, with the chart still in sight.
        page.click(parts["start"])
        page.wait_for_selector(f"{parts['end']}:enabled", timeout=15_000)
        page.evaluate("() => window.scrollTo(0, 0)")
        found = boxes(page, parts)
        for name in ("chart", "setpoint", "end"):
            assert found[name]["bottom"] <= height, (name, found[name])
        page.screenshot(path=str(artifacts / f"phone-experiment-{language}.png"))

        # The chart's data table: the newest samples, in the page's number format.
        toggle = f"figure.chart[aria-label='{messages['charts.output']}'] .chart-toggle"
        assert page.get_attribute(toggle, "aria-expanded") == "false"
        page.click(toggle)
        assert page.get_attribute(toggle, "aria-expanded") == "true"
        assert page.text_content(toggle) == messages["chart.hideTable"]
        table = f"figure.chart[aria-label='{messages['charts.output']}'] .chart-table"
        page.wait_for_function(
            "(sel) => document.querySelectorAll(sel + ' tbody tr').length === 10", arg=table
        )
        headers = page.eval_on_selector_all(f"{table} th", "ths => ths.map((t) => t.textContent)")
        assert headers == [messages["axis.time"], messages["axis.output"], messages["series.model"]]
        cells = page.eval_on_selector_all(
            f"{table} tbody td:nth-child(2)", "tds => tds.map((t) => t.textContent)"
        )
        assert all(c != "–" for c in cells)
        if language == "pt-BR":
            assert not any("." in c for c in cells)  # a decimal comma, never a point
        page.click(toggle)
        assert page.is_hidden(table)
        page.click(f"{view} button[data-action=end]")
    finally:
        page.context.close()


def unreachable_columns(page: Any) -> list[str]:
    """Headers of shown tables that cannot be brought into sight on the screen.

    A table fits, or scrolls inside its own box (overflow-x auto); each header is
    scrolled to inside that box and must then lie within it and within the screen.
    """
    found: list[str] = page.evaluate(
        """() => {
             const bad = [];
             for (const table of document.querySelectorAll('main table')) {
               if (table.offsetParent === null) continue;
               const wrap = table.closest('.table-wrap');
               const own = wrap && getComputedStyle(wrap).overflowX === 'auto';
               const fits = table.getBoundingClientRect().right <= window.innerWidth;
               if (!own && !fits) bad.push('no box: ' + table.textContent.slice(0, 40));
               for (const th of table.querySelectorAll('thead th')) {
                 if (wrap) wrap.scrollLeft = th.offsetLeft - 8;
                 const r = th.getBoundingClientRect();
                 const box = (wrap ?? table).getBoundingClientRect();
                 // Its start in sight (a column wider than the box: its first 200 px).
                 const end = Math.min(r.right, box.left + 200);
                 const inside = r.left >= box.left - 1 && end <= box.right + 1;
                 const seen = r.left >= -1 && r.left <= window.innerWidth - 20;
                 if (!inside || !seen) bad.push(th.textContent);
               }
               if (wrap) wrap.scrollLeft = 0;
             }
             return bad;
           }"""
    )
    return found


def test_a_phone_reaches_every_column_and_windows_a_long_run(
    browser: Any, phone_lab: LabServer, artifacts: Path
) -> None:
    messages = catalogue("en")
    page = log_in(browser, phone_lab, "ada", "en-US", viewport={"width": 375, "height": 812})
    view = "[data-panel-view]:not([hidden])"
    output = f"figure.chart[aria-label='{messages['charts.output']}']"
    inp = f"figure.chart[aria-label='{messages['charts.input']}']"
    try:
        page.goto(f"{phone_lab.url}/#/rig/phone-wide")
        page.click("button[data-action=ask]")
        page.wait_for_selector("button[data-action=release]:focus")
        # A run of 400 s (2 s at the twin's speed-up): longer than the windows.
        page.fill(f"{view} input[name=n]", "400")
        page.click(f"{view} button[data-action=start]")
        page.wait_for_selector(f"{view} button[data-action=end]:enabled", timeout=15_000)
        page.wait_for_selector(f"{view} button[data-action=end]:disabled", timeout=60_000)
        page.wait_for_function(
            "(sel) => document.querySelector(sel).dataset.points === '400'", arg=output
        )

        def x_span(chart: str) -> float:
            low, high = page.get_attribute(chart, "data-x-range").split(",")
            return float(high) - float(low)

        assert page.get_attribute(f"{output} [data-window=all]", "aria-pressed") == "true"
        assert x_span(output) > 390
        # The last 100 s, by finger: both charts follow, the newest samples stay in.
        page.click(f"{output} [data-window='100']")
        page.wait_for_function(
            "(sel) => document.querySelector(sel).dataset.window === '100'", arg=inp
        )
        page.wait_for_function(
            "(sel) => Number(document.querySelector(sel).dataset.points) <= 101", arg=output
        )
        assert page.get_attribute(f"{output} [data-window='100']", "aria-pressed") == "true"
        assert page.get_attribute(f"{output} [data-window=all]", "aria-pressed") == "false"
        assert 95 <= x_span(output) <= 100
        assert 95 <= x_span(inp) <= 100
        page.screenshot(path=str(artifacts / "phone-window-100.png"))
        # All again, by keyboard.
        page.focus(f"{output} [data-window=all]")
        page.keyboard.press("Enter")
        page.wait_for_function(
            "(sel) => document.querySelector(sel).dataset.points === '400'", arg=output
        )
        assert x_span(output) > 390

        # The results: θ and the verdict reachable, the page never wider than the screen.
        headers = page.eval_on_selector_all(
            f"{view} .panel-results thead th", "ths => ths.map((t) => t.textContent)"
        )
        assert messages["table.theta"] in headers
        assert messages["table.status"] in headers
        # The panel's own results fit the screen: nothing to scroll for.
        wrap = f"{view} .panel-results .table-wrap"
        assert page.eval_on_selector(wrap, "(w) => w.scrollWidth - w.clientWidth") <= 0
        assert unreachable_columns(page) == []
        assert page.evaluate(OVERFLOW) <= 0
        page.click("button[data-action=release]")
        run = page.evaluate("async () => (await (await fetch('/api/runs')).json())[0].id")
        for path, heading in ((f"#/runs/{run}", messages["run.notes"]), ("#/runs", None)):
            page.goto(f"{phone_lab.url}/{path}")
            page.wait_for_selector("main table thead th")
            if heading:
                page.wait_for_selector(f"main th:text-is('{heading}')")
                # The run's page offers the same time window over the whole record.
                windowed = "main figure.chart[data-window]"
                page.wait_for_function(
                    "(sel) => document.querySelector(sel).dataset.points === '400'", arg=windowed
                )
                page.click(f"{windowed} [data-window='500']")
                page.click(f"{windowed} [data-window='100']")
                page.wait_for_function(
                    "(sel) => Number(document.querySelector(sel).dataset.points) <= 101",
                    arg=windowed,
                )
                assert 95 <= x_span(windowed) <= 100
            assert unreachable_columns(page) == [], path
            assert page.evaluate(OVERFLOW) <= 0, path
    finally:
        page.context.close()


@pytest.mark.parametrize("locale", sorted(LOCALES))
def test_axe_finds_no_serious_violation_on_any_page(
    browser: Any, phone_lab: LabServer, locale: str
) -> None:
    language, rig, _ = LOCALES[locale]
    context = browser.new_context(locale=locale, bypass_csp=True)
    page = context.new_page()
    found: dict[str, list[str]] = {}
    try:
        page.goto(f"{phone_lab.url}/")
        page.wait_for_selector("#login-username")
        found["login"] = serious_violations(page)
        page.fill("#login-username", "tom")
        page.fill("#login-password", phone_lab.password("tom"))
        page.click("form button[type=submit]")
        page.wait_for_selector(".rig-card")
        found["lobby"] = serious_violations(page)
        page.goto(f"{phone_lab.url}/#/rig/{rig}")
        page.wait_for_selector(f"{ROLE}[data-role]")
        page.wait_for_selector("[data-panel-view]")
        found["rig"] = serious_violations(page)
        page.goto(f"{phone_lab.url}/#/runs")
        page.wait_for_selector("main h1")
        page.wait_for_timeout(500)
        found["runs"] = serious_violations(page)
        page.goto(f"{phone_lab.url}/#/teacher")
        page.wait_for_selector("main h1")
        page.wait_for_timeout(500)
        found["teacher"] = serious_violations(page)
        runs = page.evaluate("async () => (await (await fetch('/api/runs')).json())")
        if runs:
            run = runs[0]["id"]
            page.goto(f"{phone_lab.url}/#/runs/{run}")
            page.wait_for_selector("main h1")
            page.wait_for_timeout(1000)
            found["run"] = serious_violations(page)
            page.goto(f"{phone_lab.url}/#/runs/compare?ids={run}")
            page.wait_for_selector("main h1")
            page.wait_for_timeout(1000)
            found["compare"] = serious_violations(page)
    finally:
        context.close()
    assert {page_name: v for page_name, v in found.items() if v} == {}, language
