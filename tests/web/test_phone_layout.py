"""A phone doing the experiment, the charts' data tables, and axe-core on every page.

On 375 x 812 the output chart, the set point and START/END are on the first
screen together, the results right below them; each chart can show its newest
samples as a table; axe-core finds no serious or critical violation on any
page, in English and in Portuguese.
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
"""
USERS = {"pia": "student", "rui": "student", "tom": "teacher"}
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


@pytest.mark.parametrize("locale", sorted(LOCALES))
def test_a_phone_shows_the_chart_the_set_point_and_start_end_together(
    browser: Any, phone_lab: LabServer, locale: str, artifacts: Path
) -> None:
    language, rig, user = LOCALES[locale]
    messages = catalogue(language)
    page = log_in(browser, phone_lab, user, locale, viewport={"width": 375, "height": 812})
    try:
        page.goto(f"{phone_lab.url}/#/rig/{rig}")
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        view = "[data-panel-view]:not([hidden])"
        parts = {
            "chart": f"figure.chart[aria-label='{messages['charts.output']}'] .chart-plot",
            "setpoint": f"{view} input[name=setpoint-live]",
            "start": f"{view} button[data-action=start]",
            "end": f"{view} button[data-action=end]",
            "results": f"{view} .panel-results",
        }
        page.evaluate("() => window.scrollTo(0, 0)")
        found = boxes(page, parts)
        height = page.evaluate("() => window.innerHeight")
        for name in ("chart", "setpoint", "start", "end"):
            box = found[name]
            assert box is not None, name
            assert box["top"] >= 0, (name, box)
            assert box["bottom"] <= height, (name, box, height)
            assert box["left"] >= 0, (name, box)
            assert box["right"] <= 375, (name, box)
        # The results come next: right below the set point and START/END.
        assert found["results"]["top"] >= max(found[n]["bottom"] for n in ("setpoint", "end"))
        assert page.evaluate("() => document.documentElement.scrollWidth - window.innerWidth") <= 0
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
