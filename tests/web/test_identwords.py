"""The identification library's warnings and reasons in the reader's language.

js/identwords.js names each warning kind of :data:`thermolab.ident.advice.ADVICE`
and each common reason why an estimate has no model, with the catalogue keys
that say them. ADVICE stays the one declaration: the English catalogue's name
of a kind is the kind itself and its advice is ADVICE's line, word for word.

Each sentence of :data:`thermolab.ident.notes.NOTES` is read back from its
English (also after the record's units replace its volts) and said by the
catalogue's ``identNote.<code>`` with the same fields; js/identnotes.js, the
browser's copy of the patterns, is what ``python -m thermolab.web.identnotes``
writes now.
"""

from __future__ import annotations

import re
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from thermolab.ident.advice import ADVICE, warning_kind
from thermolab.ident.models import INVALID_REASONS
from thermolab.ident.notes import FINAL, NOTES, note, note_pattern, read_note
from thermolab.ident.units import in_units
from thermolab.web import STATIC_DIR
from thermolab.web.identnotes import JS_MODULE, js_module
from thermolab.web.library_words import library_sentence

sys.path.insert(0, str(Path(__file__).parent))
from test_messages import TRANSLATIONS, catalogue

IDENT = Path(__file__).parents[2] / "src" / "thermolab" / "ident"
MODULE = (STATIC_DIR / "js" / "identwords.js").read_text(encoding="utf-8")
WARNINGS = {
    kind: (name, advice)
    for kind, name, advice in re.findall(
        r'\{ kind: "([^"]+)", name: "(warningKind\.\w+)", advice: "(warningAdvice\.\w+)" \}', MODULE
    )
}
REASONS = dict(re.findall(r'\{ kind: "([^"]+)", name: "(reasonKind\.\w+)" \}', MODULE))


def test_every_warning_kind_of_advice_and_no_other_is_named() -> None:
    assert sorted(WARNINGS) == sorted(ADVICE)
    keys = [key for pair in WARNINGS.values() for key in pair] + list(REASONS.values())
    assert len(set(keys)) == len(keys)
    in_catalogue = {k for k in catalogue() if k.startswith(("warningKind.", "warningAdvice."))}
    assert in_catalogue == {key for pair in WARNINGS.values() for key in pair}


def test_the_english_words_are_advices_own() -> None:
    english = catalogue()
    for kind, (name, advice) in WARNINGS.items():
        assert english[name] == kind
        assert english[advice] == ADVICE[kind]


def test_every_language_names_each_kind_and_its_advice() -> None:
    english = catalogue()
    for language in TRANSLATIONS:
        messages = catalogue(language)
        keys = [key for pair in WARNINGS.values() for key in pair] + list(REASONS.values())
        # Said in the language (not left empty, not copied from English).
        untranslated = [k for k in keys if not messages.get(k) or messages[k] == english[k]]
        assert untranslated == [], language


def test_each_reason_kind_is_one_the_methods_give() -> None:
    source = "\n".join(p.read_text(encoding="utf-8") for p in sorted(IDENT.glob("*.py")))
    missing = [kind for kind in REASONS if not re.search(rf'f?"{re.escape(kind)}: ', source)]
    assert missing == []
    # Every reason a trajectory gives for a row with no first-order meaning is named.
    assert {warning_kind(r) for r in INVALID_REASONS if r} <= set(REASONS)


def _figures(code: str) -> dict[str, object]:
    """A value for each field of sentence ``code``: odd figures, negative where it may be."""
    values: dict[str, object] = {"message": "Maximum number of iterations has been exceeded."}
    for i, name in enumerate(note_pattern(code)[1]):
        values.setdefault(name, (-1) ** i * (0.000123456 + 37.5 * i) if i % 3 else 1500 + i)
    return values


@pytest.mark.parametrize("code", sorted(NOTES))
def test_each_sentence_reads_back_as_written_and_in_other_units(code: str) -> None:
    text = note(code, **_figures(code))
    assert warning_kind(text) in ADVICE or code in _REASON_CODES, text
    found = read_note(text)
    assert found is not None, text
    assert found[0] == code
    assert found[2] is False
    assert list(found[1]) == list(note_pattern(code)[1])
    # As a trajectory's check of its last estimate, and with a % input and a °C output.
    assert read_note(FINAL + text) == (code, found[1], True)
    celsius = read_note(in_units(text, "%", "°C"))
    assert celsius is not None
    assert celsius[0] == code


#: The sentences that say why there is no model (not warnings: their kinds are REASONS').
_REASON_CODES = {
    "no_estimate_yet", "not_excited", "unstable", "non_positive_pole", "complex_pole",
    "non_finite", "too_few_after_step", "oe_no_excitation", "too_few_to_identify",
    "input_never_changes", "no_step", "no_step_first_sample",
    # Why an estimate is not trusted: no kind of its own, said whole.
    "poor_free_run_fit", "poor_prediction", "peer_gave_no_model", "disagrees_with_peer",
    "dead_time_uncertain", "start_uncertain", "not_converged", "no_model",
}  # fmt: skip


def test_no_two_sentences_read_the_same_text() -> None:
    for code in NOTES:
        text = note(code, **_figures(code))
        assert [c for c in NOTES if __import__("re").match(note_pattern(c)[0], text)] == [code]


def test_a_sentence_of_no_code_reads_as_none() -> None:
    assert read_note("small step: a new wording nobody declared") is None
    assert read_note("") is None


def test_the_browsers_copy_of_the_patterns_is_current() -> None:
    assert JS_MODULE.read_text(encoding="utf-8") == js_module(), (
        "run: python -m thermolab.web.identnotes"
    )


def _camel(code: str) -> str:
    return re.sub(r"_([a-z])", lambda m: m.group(1).upper(), code)


@pytest.mark.parametrize("language", ["en", *TRANSLATIONS])
def test_every_sentence_is_said_in_every_language_with_its_fields(language: str) -> None:
    messages = catalogue(language)
    keys = {k for k in messages if k.startswith("identNote.")}
    assert keys == {f"identNote.{_camel(code)}" for code in NOTES}
    english = catalogue()
    for code in NOTES:
        key = f"identNote.{_camel(code)}"
        said = set(re.findall(r"\{(\w+)\}", messages[key]))  # type: ignore[arg-type]
        assert said == set(note_pattern(code)[1]), key
        assert language == "en" or messages[key] != english[key], key


def test_a_real_records_warnings_read_wholly_in_portuguese_and_spanish(module_page: Any) -> None:
    """The step method's warnings on a short, small step in % and °C: no English left."""
    from thermolab.ident import step_response

    t = np.arange(1500.0)
    u = np.where(t >= 100, 0.6, 0.0)
    rng = np.random.default_rng(7)
    y = 21.0 + 0.3 * u * (1.0 - np.exp(-np.clip(t - 110, 0, None) / 150.0))
    y = y + rng.normal(0.0, 0.002, t.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = step_response(t, u, y)
    sentences = [in_units(w, "%", "°C") for w in result.warnings]
    sentences.append(FINAL + note("gain_not_positive", K=-0.01234))
    sentences.append(note("optimiser_stopped", message="Desired error not necessarily achieved"))
    kinds_in_order = [warning_kind(w) for w in sentences]
    assert {"short record", "small step"} <= set(kinds_in_order), sentences
    r = module_page.evaluate(
        """async (sentences) => {
          const i18n = await import('/js/i18n.js');
          const { identWarning } = await import('/js/identwords.js');
          const said = (node) => ({ text: node.textContent,
            english: [...node.querySelectorAll('[lang=en]')].map((el) => el.textContent) });
          const out = {};
          for (const language of ['pt-BR', 'es', 'en']) {
            i18n.setLanguage(language, (await import(`/js/messages/${language}.js`)).messages);
            out[language] = sentences.map((s) => said(identWarning(s)));
          }
          return out;
        }""",
        sentences,
    )
    for language in TRANSLATIONS:
        shown = r[language]
        # Only the optimiser's own words stay English (marked so), nothing else.
        english = [e for s in shown for e in s["english"]]
        assert english == ["Desired error not necessarily achieved"]
        short = shown[kinds_in_order.index("short record")]["text"]
        assert "1500" in short
        assert "2000" in short
        small = shown[kinds_in_order.index("small step")]["text"]
        assert "0,6 %" in small  # the decimal comma, the unit kept
        assert "1 %" in small
        assert "-0,01234" in shown[-2]["text"]
    assert "0.6 %" in r["en"][kinds_in_order.index("small step")]["text"]


def test_why_an_estimate_is_not_trusted_reads_whole_in_the_readers_language(
    module_page: Any,
) -> None:
    """The verdict's reasons (no kind of their own) were English on a pt-BR run page."""
    sentences = [
        note("poor_free_run_fit", fit=71.25, minimum=90),
        note("disagrees_with_peer", method="oe", off="K 0.6 vs 0.5", apart=10),
        note("start_uncertain", u0=50, K=0.61, tau=151.5),
        note("not_converged"),
        note("no_model", reason=note("no_step", u=5.0)),
    ]
    r = module_page.evaluate(
        """async (sentences) => {
          const i18n = await import('/js/i18n.js');
          const { identWarning } = await import('/js/identwords.js');
          i18n.setLanguage('pt-BR', (await import('/js/messages/pt-BR.js')).messages);
          return sentences.map((s) => {
            const node = identWarning(s);
            return { text: node.textContent, english: node.querySelectorAll?.('[lang=en]').length };
          });
        }""",
        sentences,
    )
    assert r[0]["text"].startswith("ajuste ruim em simulação livre: ")
    assert "71,2 %" in r[0]["text"] or "71,3 %" in r[0]["text"]
    assert "K 0,6 vs 0,5" in r[1]["text"]
    assert r[3]["text"].startswith("a estimativa não convergiu")
    assert r[4]["text"].startswith("sem modelo: sem degrau: a entrada fica em 5 V")
    assert all(s["english"] == 0 for s in r), r
    # The command line says them in the same words.
    for sentence, shown in zip(sentences, r, strict=True):
        assert library_sentence(sentence, "pt-BR") == shown["text"]
