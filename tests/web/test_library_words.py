"""The libraries' sentences outside the browser (web.library_words), as the page says them."""

from __future__ import annotations

import string

import pytest

from thermolab.control.words import LOOP_WORDS
from thermolab.ident.advice import ADVICE
from thermolab.ident.notes import NOTES
from thermolab.web.library_words import catalogue, ident_sentence, library_sentence, loop_sentence


def _filled(template: str) -> str:
    """``template`` with a figure in every field (a name where the spec wants text)."""
    fields = {f for _l, f, _s, _c in string.Formatter().parse(template) if f}
    return template.format(**dict.fromkeys(fields, 1.5))


@pytest.mark.parametrize("language", ["pt-BR", "es"])
def test_every_warning_kind_and_note_is_said_in_the_language(language: str) -> None:
    words = catalogue(language)
    for kind in ADVICE:
        said = ident_sentence(f"{kind}: something", language)
        assert said != f"{kind}: something", kind
        assert not said.startswith(kind), said
    for code, template in NOTES.items():
        text = _filled(template)
        said = ident_sentence(text, language)
        if "{message}" not in template:  # the optimiser's own words are kept as written
            assert "1,5" in said or "1.5" not in text, (code, said)  # the figure, read back
        key = "identNote." + code.split("_")[0] + "".join(p.title() for p in code.split("_")[1:])
        assert key in words, key


@pytest.mark.parametrize("language", ["pt-BR", "es"])
def test_every_loop_word_is_said_in_the_language(language: str) -> None:
    for code, template in LOOP_WORDS.items():
        text = _filled(template)
        said = loop_sentence(text, language)
        assert said is not None, code
        assert said != text, code
        assert "{" not in said, (code, said)  # every value filled


def test_english_and_unknown_sentences_stay_as_written() -> None:
    short = NOTES["short_record"].format(n=1500, needed=2000)
    assert library_sentence(short, "en") == short
    assert library_sentence("a sentence nobody declared", "pt-BR") == "a sentence nobody declared"
    final = "final estimate: " + short
    assert library_sentence(final, "pt-BR").startswith("estimativa final: registro curto: ")
    assert "1500 amostras" in library_sentence(final, "pt-BR")
