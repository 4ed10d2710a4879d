"""The identification library's warnings and reasons in the reader's language.

js/identwords.js names each warning kind of :data:`thermolab.ident.advice.ADVICE`
and each common reason why an estimate has no model, with the catalogue keys
that say them. ADVICE stays the one declaration: the English catalogue's name
of a kind is the kind itself and its advice is ADVICE's line, word for word.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from thermolab.ident.advice import ADVICE, warning_kind
from thermolab.ident.models import INVALID_REASONS
from thermolab.web import STATIC_DIR

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
