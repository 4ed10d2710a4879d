"""The numerical libraries' sentences in a reader's language, outside the browser.

The browser says a warning or a reason of :mod:`thermolab.ident` by its kind's
name and advice and its detail's code and figures (``static/js/identwords.js``),
and a closed loop's sentence of :mod:`thermolab.control.words` by its code
(``static/js/loopwords.js``). The command line says them the same way, from the
same declarations: the catalogues ``static/js/messages/<language>.js``
(``identWords.*``, ``warningKind.*``, ``warningAdvice.*``, ``reasonKind.*``,
``identNote.*``, ``loopWord.*``), the kinds' table of ``identwords.js``, the
sentences' patterns of :mod:`thermolab.ident.notes` and the templates of
``LOOP_WORDS``, read back. A sentence no table knows, or a detail no pattern
reads, keeps the library's words for that part.
"""

from __future__ import annotations

import json
import re
from functools import cache
from typing import Any

from thermolab.control.words import LOOP_WORDS
from thermolab.ident.notes import read_note, template_pattern
from thermolab.lab.error_messages import decimal_mark
from thermolab.web import STATIC_DIR

__all__ = [
    "catalogue",
    "ident_sentence",
    "library_sentence",
    "local_figures",
    "loop_sentence",
    "method_title",
]

_JS = STATIC_DIR / "js"
#: A kind's row of identwords.js's WARNING_KINDS / REASON_KINDS.
_KIND_ROW = re.compile(r'\{ kind: "([^"]+)", name: "([^"]+)"(?:, advice: "([^"]+)")? \}')
#: A figure as the library writes it: "0.14", "-3.2e-05", "+1.50".
_FIGURE = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", re.IGNORECASE)
_FINAL = "final estimate: "
#: Fields the library copies from elsewhere (the optimiser's own words): kept as written.
_VERBATIM = {"message"}


@cache
def catalogue(language: str) -> dict[str, Any]:
    """The browser's catalogue of ``language``: the object literal of its module (JSON)."""
    text = (_JS / "messages" / f"{language}.js").read_text(encoding="utf-8")
    body = text[text.index("{", text.index("export const messages")) : text.rindex("}") + 1]
    data: dict[str, Any] = json.loads(body)
    return data


@cache
def _kinds() -> dict[str, tuple[str, str | None]]:
    """Each kind's catalogue keys (name, advice or None for a reason), from identwords.js."""
    source = (_JS / "identwords.js").read_text(encoding="utf-8")
    return {kind: (name, advice or None) for kind, name, advice in _KIND_ROW.findall(source)}


def _fill(template: str, values: dict[str, str]) -> str:
    return re.sub(r"\{(\w+)\}", lambda m: values.get(m.group(1), m.group(0)), template)


def local_figures(text: str, language: str) -> str:
    """The figures of ``text`` with the language's decimal mark, their digits as written
    (the browser's ``localFigures``, without its digits rule): for a sentence's figures
    and a report's values, never for a path, a command or output meant for a program.

    Examples
    --------
    >>> local_figures("K 0.599725 V/V, 1.5e-05 at t = 10 s", "pt-BR")
    'K 0,599725 V/V, 1,5e-05 at t = 10 s'
    """
    if language == "en":
        return text
    mark = decimal_mark(language)
    return _FIGURE.sub(lambda m: m.group().replace(".", mark), text)


def _camel(code: str) -> str:
    """``residual_dead_time`` -> ``residualDeadTime``, ``hold.no_estimate`` -> ``holdNoEstimate``.

    The catalogue keys of identwords.js and loopwords.js, derived from the codes.
    """
    return re.sub(r"[_.]([a-z])", lambda m: m.group(1).upper(), code)


def _note_key(code: str) -> str:
    return "identNote." + _camel(code)


def _note_words(sentence: str, language: str) -> str | None:
    """The note ``sentence`` is, said by its catalogue sentence (its figures in the
    language's form); None when no pattern reads it or the catalogue lacks it."""
    found = read_note(sentence)
    if found is None:
        return None
    code, fields, _final = found
    values = {
        name: value if name in _VERBATIM else local_figures(value, language)
        for name, value in fields.items()
    }
    if "reason" in fields:  # why there is no model: a sentence of its own
        said = library_sentence(fields["reason"], language)
        values["reason"] = said if said != fields["reason"] else values["reason"]
    template = catalogue(language).get(_note_key(code))
    return None if template is None else _fill(str(template), values)


def ident_sentence(text: str, language: str) -> str:
    """A warning or a reason of the identification library in ``language``.

    English is the library's own sentence. Elsewhere the kind's name (and a
    warning's advice), then its detail as the catalogue says it; a kind no table
    knows stays as written.

    Examples
    --------
    >>> ident_sentence("short record: 1500 samples, fewer than the 2000 the paper asks for "
    ...                "(the transient and the settled output must both be recorded)", "pt-BR")[:48]
    'registro curto: menos amostras do que o procedim'
    >>> ident_sentence("no step: the input never changes", "es")[:8]
    'sin esca'
    """
    if language == "en":
        return text
    words = catalogue(language)
    final = text.startswith(_FINAL)
    body = text.removeprefix(_FINAL)
    kind, colon, rest = body.partition(":")
    known = _kinds().get(kind.strip())
    if known is None:
        # A sentence of no kind (why an estimate is not trusted) is said whole.
        return _note_words(body, language) or text
    name_key, advice_key = known
    detail = (_note_words(body, language) or rest.strip()) if colon else ""
    if advice_key is None:  # a reason
        said = _fill(
            str(words["identWords.reason"]), {"kind": str(words[name_key]), "detail": detail}
        )
        return said if detail else str(words[name_key])
    key = "identWords.warning" if detail else "identWords.warningNoDetail"
    values = {"kind": str(words[name_key]), "advice": str(words[advice_key]), "detail": detail}
    said = _fill(str(words[key]), values)
    return _fill(str(words["identWords.finalEstimate"]), {"warning": said}) if final else said


@cache
def _loop_patterns() -> tuple[tuple[str, re.Pattern[str], tuple[str, ...]], ...]:
    """Each loop word's template read back (:func:`~thermolab.ident.notes.template_pattern`)."""
    rows = []
    for code, template in LOOP_WORDS.items():
        source, names = template_pattern(template)
        rows.append((code, re.compile(source, re.DOTALL), names))
    return tuple(rows)


def loop_sentence(text: str, language: str) -> str | None:
    """A closed loop's sentence (``LOOP_WORDS``) in ``language``, or None if it is none.

    A value that is itself a sentence of the identification library (why the
    tuner holds the gains) is said in the language too; figures take its
    decimal mark; a quoted name (``'zn'``) loses its quotes as in the browser.

    Examples
    --------
    >>> loop_sentence("the run was started without the model its gains came from", "pt-BR")
    'o ensaio foi iniciado sem o modelo de onde vieram os seus ganhos'
    """
    words = catalogue(language)
    for code, pattern, names in _loop_patterns():
        found = pattern.match(text)
        if found is None:
            continue
        values = {}
        for name, value in zip(names, found.groups(), strict=False):
            if name in ("warning", "reason"):
                values[name] = library_sentence(value, language)
            else:
                values[name] = local_figures(value.strip("'"), language)
        template = words.get("loopWord." + _camel(code))
        return text if template is None else _fill(str(template), values)
    return None


def library_sentence(text: str, language: str) -> str:
    """A sentence of the numerical libraries in ``language``: an identification
    warning or reason, or a closed loop's sentence; any other text as written."""
    if language == "en":
        return text
    said = ident_sentence(text, language)
    if said != text:
        return said
    looped = loop_sentence(text, language)
    return text if looped is None else looped


def method_title(name: str, language: str) -> str | None:
    """An identification method's title in ``language`` as the browser's method list
    names it (``method.<name>``), or None where the catalogue has none.

    Examples
    --------
    >>> method_title("srm", "pt-BR")
    'Resposta ao degrau (SRM)'
    """
    title = catalogue(language).get("method." + _camel(name))
    return None if title is None else str(title)
