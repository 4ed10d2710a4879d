"""The interface's message catalogue: every user-facing string in one place.

The views call ``t(key, params)`` (js/i18n.js) with literal keys of
js/messages/en.js; index.html names its keys in ``data-i18n`` attributes. These
tests fail when code holds an inline user-facing string, when a key used in
the code or the page is missing from the catalogue, when a catalogue key is
used nowhere, or when a message's placeholders differ from what its callers
pass. The heuristic for "user-facing" is below (``looks_like_text``); a string
it catches by mistake is better written as a key than hidden by a new rule.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from thermolab.web import STATIC_DIR

sys.path.insert(0, str(Path(__file__).parent))
from jsscan import Literal, literals

JS = STATIC_DIR / "js"
CATALOGUE = JS / "messages" / "en.js"
KEY = re.compile(r"^[a-z][A-Za-z0-9]*(\.[A-Za-z0-9_-]+)+$")
#: Code before a literal that makes it a name for the machine, not text for a person.
MACHINE = re.compile(
    r"""(
      \b(class|id|type|role|name|for|href|inputmode|autocomplete|tabindex|scope|method|cache|
         credentials|key|event|state|mode|dash|color|value|stroke|kind|testid|panel|download)\s*:\s*$
      | "(data-[\w-]+|aria-(controls|describedby|labelledby|hidden|selected|current|live|atomic))"
        \s*:\s*$
      | "pattern"\s*:\s*$  # identnotes.js: what reads the library's English back, never shown
      | \b(querySelector|querySelectorAll|getElementById|addEventListener|removeEventListener|
           createElement|closest|getAttribute|setAttribute|removeAttribute|startsWith|
           console\.\w+|RangeError|TypeError|import|from|column|push|has|get|includes)\s*\(\s*$
      | \bh\(\s*$
      | \bfrom\s*$
    )""",
    re.VERBOSE,
)


#: The translations of the English catalogue (js/i18n.js LANGUAGES).
TRANSLATIONS = ("pt-BR", "es")


def catalogue(language: str = "en") -> dict[str, str | dict[str, str]]:
    """A catalogue: the object literal of js/messages/<language>.js, which is JSON."""
    text = (JS / "messages" / f"{language}.js").read_text(encoding="utf-8")
    body = text[text.index("{", text.index("export const messages")) : text.rindex("}") + 1]
    data = json.loads(body)
    assert isinstance(data, dict)
    return data


def code_files() -> list[Path]:
    return sorted(p for p in JS.rglob("*.js") if "messages" not in p.relative_to(JS).parts)


def looks_like_text(lit: Literal) -> bool:
    """Whether a literal reads as words for a person (and is not a key or a machine name)."""
    s = lit.text.replace("{}", "").strip()
    if not s or KEY.match(s) or MACHINE.search(lit.before):
        return False  # a key or a machine name
    if lit.text.startswith("/") or "//" in lit.text:
        return False  # a path or a URL
    if re.fullmatch(r"GET|POST|PUT|DELETE|PATCH", s):
        return False
    if re.search(r"[A-Za-z]{2,}[^\sA-Za-z]*\s+[^\s]*[A-Za-z]", s):
        return True  # two or more words
    return bool(re.fullmatch(r"[A-Z][a-z]+|[A-Z]{3,}|[A-Z][a-z]+[.…:]", s))


def test_no_code_holds_an_inline_user_facing_string() -> None:
    found = [
        f"{p.relative_to(STATIC_DIR)}:{lit.line}: {lit.text!r}"
        for p in code_files()
        for lit in literals(p.read_text(encoding="utf-8"))
        if looks_like_text(lit)
    ]
    assert found == [], "move these strings to js/messages/en.js and call t():\n" + "\n".join(found)


def test_the_text_heuristic_catches_sentences_labels_and_buttons() -> None:
    def lit(text: str, before: str = "h('p', null, ") -> Literal:
        return Literal(text, before, 1)

    assert looks_like_text(lit("Run {} started."))
    assert looks_like_text(lit("Rigs"))
    assert looks_like_text(lit("START"))
    assert looks_like_text(lit("Loading…"))
    assert not looks_like_text(lit("panel.start"))
    assert not looks_like_text(lit("field inline", 'h("div", { class: '))
    assert not looks_like_text(lit("{}-range {}-err", '"aria-describedby": '))
    assert not looks_like_text(lit("div", "h("))


def used_keys() -> dict[str, list[str]]:
    """Every catalogue-shaped literal of the code and every data-i18n key of index.html."""
    used: dict[str, list[str]] = {}
    for p in code_files():
        for lit in literals(p.read_text(encoding="utf-8")):
            if KEY.match(lit.text):
                used.setdefault(lit.text, []).append(f"{p.relative_to(STATIC_DIR)}:{lit.line}")
    html = (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    for key in re.findall(r'data-i18n(?:-[a-z-]+)?="([^"]+)"', html):
        used.setdefault(key, []).append("index.html")
    return used


def called_keys() -> dict[str, list[str]]:
    """Keys passed literally to t() (the keys that must exist)."""
    keys: dict[str, list[str]] = {}
    for p in code_files():
        text = p.read_text(encoding="utf-8")
        for m in re.finditer(r"""\bt(?:Plural)?\(\s*["']([^"']+)["']""", text):
            line = text.count("\n", 0, m.start()) + 1
            keys.setdefault(m.group(1), []).append(f"{p.relative_to(STATIC_DIR)}:{line}")
    return keys


def test_every_key_used_is_in_the_catalogue() -> None:
    messages = catalogue()
    missing = {k: where for k, where in called_keys().items() if k not in messages}
    html = (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    in_page = re.findall(r'data-i18n(?:-[a-z-]+)?="([^"]+)"', html)
    missing |= {k: ["index.html"] for k in in_page if k not in messages}
    assert missing == {}


#: Keys looked up by name at run time: "error.<code>" translates the server's stable error
#: codes, "identNote.<code>" the identification library's sentences (test_identwords.py).
LOOKED_UP = re.compile(r"^(error|identNote)\.")


def test_every_catalogue_key_is_used() -> None:
    used = used_keys()
    unused = sorted(k for k in catalogue() if k not in used and not LOOKED_UP.match(k))
    assert unused == []


def test_catalogue_keys_are_sorted_dotted_names_and_plurals_have_other() -> None:
    messages = catalogue()
    assert list(messages) == sorted(messages), "keep the catalogue sorted: translators diff it"
    for key, value in messages.items():
        assert KEY.match(key), key
        if isinstance(value, dict):
            assert "other" in value, f"{key}: a plural message needs its 'other' form"
            assert set(value) <= {"zero", "one", "two", "few", "many", "other"}, key


@pytest.mark.parametrize("key", sorted(catalogue()))
def test_placeholders_are_named(key: str) -> None:
    value = catalogue()[key]
    forms = value.values() if isinstance(value, dict) else [value]
    for form in forms:
        for name in re.findall(r"\{([^}]*)\}", form):
            assert re.fullmatch(r"[A-Za-z][A-Za-z0-9]*", name), f"{key}: placeholder {{{name}}}"


def test_the_page_shell_names_its_keys() -> None:
    html = (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    body = html[html.index("<body>") :]
    # Every element with words in it says which message it shows (the brand is a name).
    text_elements = re.findall(r"<(\w+)([^>]*)>([^<]*[A-Za-z]{2,}[^<]*)</\1>", body)
    bare = [
        (tag, text)
        for tag, attrs, text in text_elements
        if "data-i18n" not in attrs and text != "ThermoLab"
    ]
    assert bare == []


def test_every_language_of_the_interface_has_a_catalogue() -> None:
    i18n = (JS / "i18n.js").read_text(encoding="utf-8")
    declared = re.findall(r'^\s*"?([A-Za-z-]+)"?: \{ name: "language\.', i18n, re.MULTILINE)
    assert sorted(declared) == sorted(["en", *TRANSLATIONS])
    for tag in TRANSLATIONS:
        assert f'import("./messages/{tag}.js")' in i18n


@pytest.mark.parametrize("language", TRANSLATIONS)
def test_a_translation_has_every_key_and_no_other(language: str) -> None:
    english, translated = catalogue(), catalogue(language)
    assert sorted(set(english) - set(translated)) == [], "untranslated keys"
    assert sorted(set(translated) - set(english)) == [], "keys English does not have"
    assert list(translated) == sorted(translated), "keep the catalogue sorted: translators diff it"


def forms(message: str | dict[str, str]) -> list[str]:
    return list(message.values()) if isinstance(message, dict) else [message]


def placeholders(text: str) -> set[str]:
    return set(re.findall(r"\{([A-Za-z0-9]+)\}", text))


@pytest.mark.parametrize("language", TRANSLATIONS)
def test_a_translation_keeps_the_placeholders_and_plural_forms(language: str) -> None:
    english, translated = catalogue(), catalogue(language)
    wrong = []
    for key, message in english.items():
        other = translated[key]
        if isinstance(message, dict) != isinstance(other, dict):
            wrong.append(f"{key}: plural forms in one language and not the other")
            continue
        if isinstance(other, dict):
            if "other" not in other or not set(other) <= {
                "zero",
                "one",
                "two",
                "few",
                "many",
                "other",
            }:
                wrong.append(f"{key}: plural forms {sorted(other)}")
            if "zero" in message and "zero" not in other:
                wrong.append(f"{key}: English says 'zero' apart; so must the translation")
        wanted = set().union(*(placeholders(f) for f in forms(message)))
        for form in forms(other):
            if placeholders(form) != wanted and not (
                # A singular form may spell the number out ("um minuto").
                isinstance(other, dict) and placeholders(form) == wanted - {"count"}
            ):
                wrong.append(f"{key}: {sorted(placeholders(form))} instead of {sorted(wanted)}")
    assert wrong == []


#: Words that are the same in every language of the lab: names, units, symbols,
#: the paper's method acronyms and the languages' own names (autonyms).
SAME_IN_EVERY_LANGUAGE = {
    "ThermoLab", "Ks", "Ts", "CSV", "JSON", "PID", "FIFO", "LSM", "MALSM", "WLSM", "SRM",
    "pmax", "W0", "a0", "b0", "Hz", "V", "s", "u", "y", "t", "k", "P", "I", "θ",
    "English", "Español", "Português", "Brasil",
    "Kp", "Ti", "Td", "IAE",  # the PID's gains and the integral of the absolute error
}  # fmt: skip
#: Messages whose words happen to be the same in a language (checked one by one).
SAME_BY_CHANCE = {
    ("pt-BR", "run.inputManual"),  # "manual" is Portuguese too
    ("es", "run.inputManual"),  # and Spanish
    ("es", "panel.legend"),  # "Panel" is Spanish too
    ("es", "nav.lti"),  # "LMS" is the Spanish abbreviation too
}


def untranslated_words(text: str) -> list[str]:
    """The words of a message that are neither placeholders nor the same in every language."""
    words = re.findall(r"[^\W\d_]+\d*", re.sub(r"\{[A-Za-z0-9]+\}", " ", text))
    return [w for w in words if w not in SAME_IN_EVERY_LANGUAGE]


def paired_forms(
    english: str | dict[str, str], other: str | dict[str, str]
) -> list[tuple[str, str]]:
    """A message's English forms with the translation's, by plural category."""
    if isinstance(english, dict) and isinstance(other, dict):
        return [(english[c], other[c]) for c in english if c in other]
    return [(str(english), str(other))]


@pytest.mark.parametrize("language", TRANSLATIONS)
def test_no_message_is_left_in_english(language: str) -> None:
    english, translated = catalogue(), catalogue(language)
    left = [
        f"{key}: {english_form!r}"
        for key, message in english.items()
        if (language, key) not in SAME_BY_CHANCE
        for english_form, form in paired_forms(message, translated[key])
        if form == english_form and untranslated_words(form)
    ]
    assert left == [], f"translate these into {language}"


def test_the_untranslated_check_catches_english_and_passes_symbols() -> None:
    assert untranslated_words("Run {run} started.") == ["Run", "started"]
    assert untranslated_words("{page} · ThermoLab") == []
    assert untranslated_words("Ts (s)") == []
    assert untranslated_words("Ks(k)") == []
    assert untranslated_words("Download the samples (CSV)") == ["Download", "the", "samples"]


@pytest.mark.parametrize("language", TRANSLATIONS)
def test_a_translation_writes_numbers_with_its_decimal_comma(language: str) -> None:
    # pt-BR and es write 0,140090: a number copied from English with a point is a slip.
    slips = [
        f"{key}: {form!r}"
        for key, message in catalogue(language).items()
        for form in forms(message)
        if re.search(r"(?<![\w.])\d+\.\d+", form)
    ]
    assert slips == []


#: Words a language's messages do not use, each with the glossary term that says it
#: (js/glossary.js): one word per concept, so a student never wonders whether the
#: "bancada" and the "equipamento" are two things.
NOT_THE_TERM = {
    "pt-BR": {
        r"\bequipamentos?\b": "glossary.rig",
        # The closed loop's is "referência", an open loop's input "entrada".
        r"\bset ?points?\b": "glossary.setpoint",
    },
    "es": {
        r"\bbancos?\b": "glossary.rig",
        r"\bconsignas?\b": "glossary.setpoint",
        r"\bset ?points?\b": "glossary.setpoint",
    },
    "en": {r"\bbench(es)?\b": "glossary.rig", r"\bsetpoints?\b": "glossary.setpoint"},
}


@pytest.mark.parametrize("language", ["en", *TRANSLATIONS])
def test_each_concept_has_one_word_the_glossarys(language: str) -> None:
    messages = catalogue(language)
    wrong = [
        f"{key}: {pattern} (say {messages[term]!r})"
        for key, message in messages.items()
        for form in forms(message)
        for pattern, term in NOT_THE_TERM[language].items()
        if re.search(pattern, re.sub(r"\{[A-Za-z0-9]+\}", " ", form), re.IGNORECASE)
    ]
    assert wrong == []
    # The role labels are the glossary's words, which fit a woman and a man alike.
    assert messages["role.teacher"] == messages["glossary.teacher"]
    assert messages["role.student"] == messages["glossary.student"] or language == "pt-BR"


def test_the_default_rigs_title_is_the_lab_s_own_words() -> None:
    # The browser translates the shipped default rig's title (shapes.js rigTitle):
    # the English catalogue holds it as the configuration writes it.
    from thermolab.lab.config.model import DEFAULT_RIG

    assert catalogue()["rig.defaultTitle"] == DEFAULT_RIG.title
