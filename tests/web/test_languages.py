"""The interface's languages, in a real Chromium: choosing one, loading its
catalogue, and numbers written and read in its form (decimal comma in pt-BR
and es).

Each test leaves the page speaking English again, so the modules' shared
state does not leak into the next test.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.browser

BACK_TO_ENGLISH = """
  const i18n = await import('/js/i18n.js');
  i18n.setLanguage('en', (await import('/js/messages/en.js')).messages);
  localStorage.removeItem(i18n.LANGUAGE_STORAGE_KEY);
"""


def run_js(page: Any, body: str, arg: Any = None) -> Any:
    """Run an async function body in the page (``arg`` is its argument) and return its result."""
    return page.evaluate(
        f"async (arg) => {{ try {{ {body} }} finally {{ {BACK_TO_ENGLISH} }} }}", arg
    )


@pytest.mark.parametrize(
    ("preferences", "expected"),
    [
        (["pt-BR", "en"], "pt-BR"),
        (["pt"], "pt-BR"),
        (["pt-PT", "en"], "pt-BR"),
        (["es-MX", "pt-BR"], "es"),
        (["es-419"], "es"),
        (["fr-FR", "de", "es"], "es"),
        (["en-GB", "pt-BR"], "en"),
        (["EN-us"], "en"),
        (["fr", "de"], "en"),
        ([], "en"),
        (["", "  "], "en"),
    ],
)
def test_the_language_is_the_best_match_of_the_browsers_preferences(
    module_page: Any, preferences: list[str], expected: str
) -> None:
    got = run_js(
        module_page,
        "const i18n = await import('/js/i18n.js'); return i18n.negotiateLanguage(arg);",
        preferences,
    )
    assert got == expected


def test_a_chosen_language_is_loaded_on_demand_and_remembered(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const before = {
          lang: i18n.language(), rigs: i18n.t('nav.rigs'), html: document.documentElement.lang,
        };
        const chosen = await i18n.useLanguage('pt-BR', { remember: true });
        const pt = {
          chosen, lang: i18n.language(), html: document.documentElement.lang,
          rigs: i18n.t('nav.rigs'), stored: localStorage.getItem(i18n.LANGUAGE_STORAGE_KEY),
          preferred: i18n.preferredLanguage(),
          plural: [1, 2].map((count) => i18n.t('duration.seconds', { count })),
        };
        const es = { chosen: await i18n.useLanguage('es-AR'), rigs: i18n.t('nav.rigs'),
                     stored: localStorage.getItem(i18n.LANGUAGE_STORAGE_KEY) };
        return { before, pt, es };
        """,
    )
    assert r["before"] == {"lang": "en", "rigs": "Rigs", "html": "en"}
    assert r["pt"] == {
        "chosen": "pt-BR",
        "lang": "pt-BR",
        "html": "pt-BR",
        "rigs": "Bancadas",
        "stored": "pt-BR",
        "preferred": "pt-BR",
        "plural": ["1 segundo", "2 segundos"],
    }
    # Not remembered unless asked: the stored choice stays pt-BR.
    assert r["es"] == {"chosen": "es", "rigs": "Equipos", "stored": "pt-BR"}


def test_a_stored_choice_that_is_no_language_falls_back_to_the_browser(module_page: Any) -> None:
    got = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        localStorage.setItem(i18n.LANGUAGE_STORAGE_KEY, 'xx-YY');
        return [i18n.preferredLanguage(), i18n.negotiateLanguage(navigator.languages)];
        """,
    )
    assert got[0] == got[1]


@pytest.mark.parametrize("language", ["pt-BR", "es"])
def test_numbers_are_written_with_the_languages_decimal_comma(
    module_page: Any, language: str
) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { fmt } = await import('/js/model.js');
        const { rangeText, checkNumber } = await import('/js/validate.js');
        const { tickLabels } = await import('/js/charts.js');
        await i18n.useLanguage(arg);
        return {
          fmt: [fmt(0.1400901234), fmt(250.126233), fmt(-3.5), fmt(12345.678), fmt(1e-6, 3),
                fmt(NaN)],
          decimal: [-0.96, 2000, 9.9082e-4].map((v) => i18n.formatDecimal(v)),
          message: i18n.t('run.seconds', { seconds: 1.5 }),
          wholeStaysPlain: i18n.t('runs.label', { run: 12345 }),
          range: rangeText({ label: 'x', min: -10, max: 10.5, unit: 'V' }),
          refused: checkNumber('11,5', { label: 'u', min: -10, max: 10.5 }),
          ticks: tickLabels(null, [0, 0.25, 0.5], 1, 0, 0.25),
          wholeTicks: tickLabels(null, [0, 500, 1000], 0, 0, 500),
        };
        """,
        language,
    )
    assert r["fmt"] == ["0,14009", "250,126", "-3,5", "12345,7", "1,00e-6", "–"]
    assert r["decimal"] == ["−0,96", "2000", "0,00099082"]
    assert r["message"] == "1,5 s"
    assert r["wholeStaysPlain"].endswith("12345")
    assert "−10" in r["range"]
    assert "10,5 V" in r["range"]
    assert r["refused"]["ok"] is False
    assert "11,5" in r["refused"]["error"]
    assert r["ticks"] == ["0,00", "0,25", "0,50"]
    assert r["wholeTicks"] == ["0", "500", "1000"]


def test_english_keeps_the_decimal_point(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { fmt } = await import('/js/model.js');
        const { tickLabels } = await import('/js/charts.js');
        return [fmt(250.126233), i18n.formatDecimal(-0.96), ...tickLabels(null, [0.5], 1, 0, 0.5)];
        """,
    )
    assert r == ["250.126", "−0.96", "0.5"]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("0,96", 0.96),
        ("0.96", 0.96),
        (" −1,5 ", -1.5),
        ("-2", -2.0),
        (",5", 0.5),
        ("1,5e-4", 1.5e-4),
        ("1.000,5", None),  # grouped thousands: two marks, not guessed at
        ("1,000.5", None),
        ("1,2,3", None),
        ("0x10", None),
        ("", None),
        ("1 000", None),
        ("abc", None),
    ],
)
def test_typed_numbers_accept_a_decimal_comma_and_refuse_ambiguity(
    module_page: Any, text: str, expected: float | None
) -> None:
    got = run_js(
        module_page,
        "const { parseDecimal } = await import('/js/validate.js'); return parseDecimal(arg);",
        text,
    )
    if expected is None:
        assert got is None
    else:
        assert got == pytest.approx(expected, rel=1e-15, abs=0)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=40),
    st.sampled_from(["pt-BR", "en", "es"]),
)
def test_a_number_shown_in_a_field_reads_back_as_the_same_number(
    module_page: Any, values: list[float], language: str
) -> None:
    # The law behind form defaults: what formatDecimal writes, parseDecimal reads back exactly.
    back = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { parseDecimal } = await import('/js/validate.js');
        await i18n.useLanguage(arg.language);
        return arg.values.map((v) => parseDecimal(i18n.formatDecimal(v)));
        """,
        {"values": values, "language": language},
    )
    for value, read in zip(values, back, strict=True):
        assert read is not None
        # float(): Playwright hands a large whole JS number over as a Python int.
        assert math.copysign(1.0, read) == math.copysign(1.0, value) or value == 0.0
        assert float(read) == value  # exact: the shortest round-trip form, no rounding


def test_a_server_error_is_translated_by_its_code_else_shown_as_sent(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { errorMessage } = await import('/js/api.js');
        const pt = (await import('/js/messages/pt-BR.js')).messages;
        i18n.setLanguage('pt-BR', { ...pt, 'error.rig_busy': 'A bancada {rig} está ocupada.' });
        return [
          errorMessage({ detail: 'Rig twin is busy.', code: 'rig_busy', params: { rig: 'twin' } },
                       '?'),
          errorMessage({ detail: { code: 'rig_busy', message: 'Rig x is busy.',
                                   params: { rig: 'x' } } }, '?'),
          errorMessage({ detail: 'Something new.', code: 'not_in_catalogue' }, '?'),
          errorMessage({ detail: { code: 'not_in_catalogue' } }, 'fallback'),
          errorMessage({ detail: 'Plain.' }, '?'),
          i18n.serverMessage('../evil', 'as sent'),
        ];
        """,
    )
    assert r == [
        "A bancada twin está ocupada.",
        "A bancada x está ocupada.",
        "Something new.",
        "fallback",
        "Plain.",
        "as sent",
    ]


def test_the_servers_translated_sentence_is_shown_on_a_page_not_in_english(
    module_page: Any,
) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { errorMessage } = await import('/js/api.js');
        const body = { detail: 'no rig called x', code: 'not_found',
                       message: 'Nada foi encontrado ali.' };
        await i18n.useLanguage('en');
        const english = errorMessage(body, '?');
        await i18n.useLanguage('pt-BR');
        return [english, errorMessage(body, '?'), errorMessage({ detail: 'd', code: 'x' }, '?')];
        """,
    )
    assert r == ["no rig called x", "Nada foi encontrado ali.", "d"]


def test_the_servers_own_sentences_are_marked_as_english_on_other_pages(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { serverText, tParts } = await import('/js/dom.js');
        const show = (parts) =>
          parts.map((p) => typeof p === 'string' ? p : `<${p.lang}>${p.textContent}`);
        const english = show(tParts('panel.endedWhy',
          { run: 3, status: 'stopped', reason: serverText('stopped by the teacher') }));
        await i18n.useLanguage('pt-BR');
        const pt = show(tParts('panel.endedWhy',
          { run: 3, status: 'parado', reason: serverText('stopped by the teacher') }));
        return { english, pt };
        """,
    )
    assert r["english"] == ["Run #3 stopped (stopped by the teacher)."]
    assert r["pt"] == ["Ensaio nº 3 parado (", "<en>stopped by the teacher", ")."]
