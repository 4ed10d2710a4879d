"""The key pages in each language, in a real Chromium against a real lab.

The browser's language preference (Playwright's ``locale``, which sets
``navigator.languages``) picks the interface's language; the page is then read
as a student sees it: any piece of an English message visible on a Brazilian
or Spanish page fails the test (login, lobby, rig page with its three panels,
a run made in that language, My runs, the comparison and the run's page). The run is started
with a decimal comma typed in the sample-time field; what is sent to the API
is a JSON number.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_messages import SAME_IN_EVERY_LANGUAGE, catalogue, forms

pytestmark = pytest.mark.browser

RIG = "twin-lang"
USER = "lucia"
ROLE = "[data-testid=access-role]"
#: What the page shows in each language: <html lang>, a word of the nav bar and the decimal mark.
LANGUAGES = {
    "pt-BR": {"locale": "pt-BR", "lang": "pt-BR", "rigs": "Bancadas", "mark": ","},
    "es": {"locale": "es-MX", "lang": "es", "rigs": "Equipos", "mark": ","},
    "en": {"locale": "en-GB", "lang": "en", "rigs": "Rigs", "mark": "."},
}
#: Text the lab's configuration and data bring, not the interface (rig titles).
NOT_INTERFACE = re.compile(r"Twin for the \w+ tests?")


def english_pieces(language: str) -> list[str]:
    """The pieces of English messages (between placeholders) a translated page must not show.

    A piece whose words are the same in every language, or that the
    translation itself uses ("Panel" in Spanish), is not a sign of English.
    """
    translated = " \n ".join(f for m in catalogue(language).values() for f in forms(m))
    pieces = set()
    for message in catalogue().values():
        for form in forms(message):
            for piece in re.split(r"\{[A-Za-z0-9]+\}", form):
                piece = piece.strip(" .,:;()·›–-…")
                words = re.findall(r"[^\W\d_]+", piece)
                if not words or all(w in SAME_IN_EVERY_LANGUAGE for w in words):
                    continue
                if re.search(rf"(?<!\w){re.escape(piece)}(?!\w)", translated):
                    continue
                pieces.add(piece)
    return sorted(pieces, key=len, reverse=True)


def visible_text(page: Any) -> str:
    """What a reader meets: the page's visible text, its title and the names given to controls.

    The options of the language switcher are marked with their own ``lang`` and
    left out, as are the server's sentences marked ``lang="en"``.
    """
    return str(
        page.evaluate(
            """() => {
              const sel = '[aria-label], [title], [alt], [placeholder]';
              const named = [...document.querySelectorAll(sel)]
                .filter((el) => el.getClientRects().length > 0)
                .flatMap((el) => ['aria-label', 'title', 'alt', 'placeholder']
                  .map((a) => el.getAttribute(a)).filter(Boolean));
              // Text marked as another language (lang="en": the server's own
              // sentences, which have no code to translate them by yet) is declared, not missed.
              const page = document.documentElement.lang;
              const marked = [...document.body.querySelectorAll('[lang]')]
                .filter((el) => el.getAttribute('lang') !== page);
              const saved = marked.map((el) => [el, el.textContent]);
              for (const el of marked) el.textContent = '';
              const text = document.body.innerText;
              for (const [el, t] of saved) el.textContent = t;
              return [document.title, text, ...named].join('\\n');
            }"""
        )
    )


def assert_no_english(page: Any, language: str, where: str) -> None:
    if language == "en":
        return
    text = NOT_INTERFACE.sub(" ", visible_text(page))
    left = [p for p in english_pieces(language) if re.search(rf"(?<!\w){re.escape(p)}(?!\w)", text)]
    lines = [
        line
        for line in text.splitlines()
        if any(re.search(rf"(?<!\w){re.escape(p)}(?!\w)", line) for p in left)
    ]
    assert left == [], f"{where} in {language} shows English: {left} in {lines}"


def test_the_english_check_sees_english() -> None:
    # The check itself: an English message on a Brazilian page is found, its translation is not.
    pieces = english_pieces("pt-BR")
    assert "Ask for control" in pieces
    assert "Queue" in pieces
    assert "Panel" in pieces  # English for pt-BR, not for es
    assert "Panel" not in english_pieces("es")
    assert "ThermoLab" not in pieces


def wait_role(page: Any, role: str) -> None:
    page.wait_for_function(
        "([sel, role]) => document.querySelector(sel)?.dataset.role === role",
        arg=[ROLE, role],
        timeout=15_000,
    )


@pytest.mark.parametrize("language", list(LANGUAGES))
def test_the_key_pages_speak_the_browsers_language(
    browser: Any, lab: Any, language: str, artifacts: Path
) -> None:
    want = LANGUAGES[language]
    context = browser.new_context(locale=want["locale"], viewport={"width": 1280, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        # Login: the language comes from the browser, before anyone logs in.
        page.goto(f"{lab.url}/")
        page.wait_for_selector("#login-username")
        assert page.get_attribute("html", "lang") == want["lang"]
        assert page.input_value("#language") == want["lang"]
        assert_no_english(page, language, "the login page")
        page.fill("#login-username", USER)
        page.fill("#login-password", lab.password(USER))
        page.click("form button[type=submit]")
        page.wait_for_selector("#nav:not([hidden])")

        # Lobby.
        page.wait_for_selector(f".rig-card[data-rig={RIG}]")
        assert page.inner_text("#nav a[data-nav=lobby]") == want["rigs"]
        assert_no_english(page, language, "the lobby")

        # The rig page with each of its three panels, as a watcher then as the controller.
        page.goto(f"{lab.url}/#/rig/{RIG}")
        wait_role(page, "watcher")
        for panel in ("srm-lsm", "malsm", "wlsm"):
            page.click(f"[role=tab][data-panel={panel}]")
            page.wait_for_selector(f"[data-panel-view={panel}]:visible")
            assert_no_english(page, language, f"the rig page (panel {panel})")
        page.click("button[data-action=ask]")
        wait_role(page, "controller")
        # The default values are shown in the language's form, and a decimal comma is accepted.
        page.click("[role=tab][data-panel=wlsm]")
        assert page.input_value("#wlsm-a0") == f"0{want['mark']}96329"
        page.click("[role=tab][data-panel=srm-lsm]")
        page.fill("#srm-lsm-dt", "0,5")
        page.fill("#srm-lsm-n", "40")
        page.fill("#srm-lsm-setpoint", "2,5")
        with page.expect_request(lambda r: r.url.endswith(f"/api/rigs/{RIG}/runs")) as sent:
            page.click("[data-panel-view=srm-lsm] button[data-action=start]")
        body = json.loads(sent.value.post_data or "{}")
        assert body["dt"] == 0.5
        assert isinstance(body["dt"], float)
        assert body["samples"] == 40
        finished = catalogue(language)["runStatus.finished"]
        page.wait_for_function(
            """finished => document.querySelector('[data-testid=run-status-srm-lsm]')
                 ?.textContent.includes(finished)""",
            arg=finished,
            timeout=60_000,
        )
        readout = page.inner_text("[data-readout=u]")
        assert readout in ("0", f"2{want['mark']}5")
        assert_no_english(page, language, "the rig page after a run")
        page.screenshot(path=str(artifacts / f"rig-{language}.png"), full_page=True)
        page.click("button[data-action=release]")
        wait_role(page, "watcher")

        # My runs, then the run's page.
        page.click("#nav a[data-nav=runs]")
        page.wait_for_selector("table.runs tbody tr")
        assert_no_english(page, language, "My runs")
        # The comparison with the reference model (the paper's Table I).
        page.check("table.runs tbody tr:first-child input[name=run]")
        page.click("main button.primary[type=submit]")
        page.wait_for_selector("table.compare tbody tr")
        assert f"0{want['mark']}14009" in page.inner_text("main")  # the reference Ks
        assert_no_english(page, language, "the comparison")
        page.go_back()
        page.wait_for_selector("table.runs tbody tr")
        page.click("table.runs tbody tr:first-child a")
        page.wait_for_selector("[data-testid=csv-link]")
        assert f"0{want['mark']}5" in page.inner_text("main")  # the sample time, 0.5 s
        assert_no_english(page, language, "the run's page")
        page.screenshot(path=str(artifacts / f"run-{language}.png"), full_page=True)
        assert errors == []
    finally:
        context.close()


def test_the_language_switcher_changes_the_page_in_place_and_is_remembered(
    logged_in: Any, lab: Any
) -> None:
    context = logged_in(USER, locale="en-US", viewport={"width": 1280, "height": 900})
    page = context.new_page()
    try:
        page.goto(f"{lab.url}/#/rig/{RIG}")
        wait_role(page, "watcher")
        assert page.inner_text("#nav a[data-nav=lobby]") == "Rigs"
        page.evaluate("() => { window.__sameDocument = true; }")
        page.focus("#language")
        page.select_option("#language", "pt-BR")
        page.wait_for_function("() => document.documentElement.lang === 'pt-BR'")
        wait_role(page, "watcher")
        page.wait_for_selector("button[data-action=ask]:text('Pedir o controle')")
        assert page.inner_text("#nav a[data-nav=lobby]") == "Bancadas"
        assert page.evaluate("() => window.__sameDocument") is True  # no reload
        assert page.evaluate("() => document.activeElement.id") == "language"
        assert_no_english(page, "pt-BR", "the rig page after switching")
        # Remembered: a new visit in an English browser speaks Portuguese.
        page.reload()
        page.wait_for_function("() => document.documentElement.lang === 'pt-BR'")
        assert page.input_value("#language") == "pt-BR"
        page.select_option("#language", "en")
        page.wait_for_function("() => document.documentElement.lang === 'en'")
    finally:
        context.close()
