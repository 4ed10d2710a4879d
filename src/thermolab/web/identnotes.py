"""The browser's copy of the identification library's sentence patterns.

``static/js/identnotes.js`` is written from :data:`thermolab.ident.notes.NOTES`
by ``python -m thermolab.web.identnotes``; tests/web/test_identwords.py fails
when it is not current. Nothing is built at install or serve time: the file is
committed, as every other module of the interface.
"""

from __future__ import annotations

import json
import sys

from thermolab.ident.notes import NOTES, note_pattern
from thermolab.web import STATIC_DIR

__all__ = ["JS_MODULE", "js_module"]

JS_MODULE = STATIC_DIR / "js" / "identnotes.js"


def js_module() -> str:
    """The text of ``static/js/identnotes.js``: each code's pattern and field names."""
    rows = [
        {"code": code, "pattern": source, "fields": list(names)}
        for code in NOTES
        for source, names in [note_pattern(code)]
    ]
    body = ",\n".join(f"  {json.dumps(row, ensure_ascii=False)}" for row in rows)
    return (
        "// @ts-check\n"
        "// Written by `python -m thermolab.web.identnotes` from thermolab/ident/notes.py: do\n"
        "// not edit. The patterns that read the identification library's sentences back;\n"
        "// identwords.js fills each code's template of the catalogue with the fields.\n\n"
        "/** @type {ReadonlyArray<{code: string, pattern: string, fields: string[]}>} */\n"
        f"export const NOTE_PATTERNS = [\n{body},\n];\n"
    )


if __name__ == "__main__":
    JS_MODULE.write_text(js_module(), encoding="utf-8")
    sys.stdout.write(f"wrote {JS_MODULE}\n")
