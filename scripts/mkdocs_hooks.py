"""MkDocs hooks: the HTTP API reference, generated from the app at build time.

``mkdocs.yml`` names this file under ``hooks:``. At every build it builds the
lab's FastAPI application from *this* checkout's ``src/`` (a default lab in a
temporary folder: nothing is started, nothing is fetched), asks it for its
OpenAPI document and adds two generated pages to the site:

* ``reference/openapi.json`` -- the document itself, as ``/openapi.json`` serves it;
* ``reference/http-api.md`` -- a Markdown reference rendered from it: one section
  per tag, one entry per operation (parameters, body, answers), then the schemas.

Nothing is written into the repository.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

METHODS = ("get", "post", "put", "patch", "delete")


def openapi_document(root: Path) -> dict[str, Any]:
    """Build the lab's app from ``root/src`` and return its OpenAPI document."""
    src = str(root / "src")
    if sys.path[0] != src:
        sys.path.insert(0, src)
    from thermolab.lab.config import default_config
    from thermolab.lab.http.app import create_app

    with tempfile.TemporaryDirectory() as tmp:
        return create_app(default_config(Path(tmp)), sweep_interval=None).openapi()


def _cell(text: object) -> str:
    """One table cell: a single line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


#: Display names of the components (set by :func:`render`): FastAPI names a
#: component ``thermolab__lab__http__schemas__RigOut`` when two share a class name.
_NAMES: dict[str, str] = {}


def _short_names(components: list[str]) -> dict[str, str]:
    """``RigOut`` for each component, ``RigOut (lab.http.schemas)`` where two share it."""
    last = [c.rsplit("__", 1)[-1] for c in components]
    names = {}
    for full, short in zip(components, last, strict=True):
        if last.count(short) > 1 and "__" in full:
            module = full.rsplit("__", 1)[0].replace("__", ".").removeprefix("thermolab.")
            names[full] = f"{short} ({module})"
        else:
            names[full] = short
    return names


def _type(schema: dict[str, Any]) -> str:
    """A short name for a schema: its component's name, or its JSON type."""
    if "$ref" in schema:
        full = str(schema["$ref"]).rsplit("/", 1)[-1]
        return "`" + _NAMES.get(full, full) + "`"
    if "anyOf" in schema:
        return " or ".join(_type(s) for s in schema["anyOf"])
    if "allOf" in schema and len(schema["allOf"]) == 1:
        return _type(schema["allOf"][0])
    kind = schema.get("type")
    if kind == "array":
        return "array of " + _type(schema.get("items", {}))
    if "enum" in schema:
        return " | ".join(f"`{v}`" for v in schema["enum"])
    if "const" in schema:
        return f"`{schema['const']}`"
    return f"{kind}" if kind else "any"


def _bounds(schema: dict[str, Any]) -> str:
    parts = []
    for key, sign in (
        ("minimum", "≥"),
        ("exclusiveMinimum", ">"),
        ("maximum", "≤"),
        ("exclusiveMaximum", "<"),
        ("minLength", "length ≥"),
        ("maxLength", "length ≤"),
        ("maxItems", "items ≤"),
    ):
        if key in schema:
            parts.append(f"{sign} {schema[key]}")
    if "default" in schema:
        parts.append(f"default `{json.dumps(schema['default'])}`")
    return ", ".join(parts)


def _description(operation: dict[str, Any]) -> str:
    """The operation's description up to its numpydoc sections (those are for Python)."""
    lines: list[str] = []
    for line in operation.get("description", "").splitlines():
        if set(line.strip()) == {"-"}:
            if lines:
                lines.pop()  # the section's title, underlined by this line
            break
        lines.append(line)
    return "\n".join(lines).strip()


def render(spec: dict[str, Any]) -> str:
    """The Markdown reference page of an OpenAPI document."""
    info = spec["info"]
    components = spec.get("components", {}).get("schemas", {})
    _NAMES.clear()
    _NAMES.update(_short_names(sorted(components)))
    out = [
        "# HTTP API reference",
        "",
        "*For script writers and integrators. Generated at build time from the lab's "
        "own OpenAPI document ([`openapi.json`](openapi.json)); a running lab also "
        "serves it at `/openapi.json`, with Swagger UI at `/docs`.*",
        "",
        f"{info['title']} {info['version']}. {info.get('description', '')}",
        "",
        "Errors share one shape: an HTTP status, a stable `code`, an English `detail` "
        "and `message`, the code's sentence in the reader's language.",
        "",
    ]
    by_tag: dict[str, list[tuple[str, str, dict[str, Any]]]] = {}
    for path, item in spec["paths"].items():
        for method in METHODS:
            if method in item:
                op = item[method]
                for tag in op.get("tags", ["other"]):
                    by_tag.setdefault(tag, []).append((method, path, op))
    for tag in sorted(by_tag):
        out += [f"## {tag.upper() if tag == 'lti' else tag.capitalize()}", ""]
        for method, path, op in by_tag[tag]:
            out += [f"### `{method.upper()} {path}`", ""]
            if op.get("summary"):
                out += [f"**{op['summary']}.**", ""]
            text = _description(op)
            if text:
                out += [text, ""]
            params = op.get("parameters", [])
            if params:
                out += [
                    "| Parameter | In | Type | Required | Bounds | Description |",
                    "|---|---|---|---|---|---|",
                ]
                for p in params:
                    schema = p.get("schema", {})
                    out.append(
                        f"| `{p['name']}` | {p['in']} | {_cell(_type(schema))} | "
                        f"{'yes' if p.get('required') else 'no'} | {_cell(_bounds(schema))} | "
                        f"{_cell(p.get('description', schema.get('description', '')))} |"
                    )
                out.append("")
            body = op.get("requestBody")
            if body:
                for media, content in body.get("content", {}).items():
                    out += [f"Body ({media}): {_type(content.get('schema', {}))}.", ""]
            answers = []
            for code, answer in op.get("responses", {}).items():
                schemas = [
                    _type(c["schema"]) for c in answer.get("content", {}).values() if "schema" in c
                ]
                kind = f" — {schemas[0]}" if schemas and schemas[0] != "any" else ""
                answers.append(f"- **{code}** {_cell(answer.get('description', ''))}{kind}")
            if answers:
                out += ["Answers:", "", *answers, ""]
    out += ["## Schemas", ""]
    for name, schema in sorted(components.items(), key=lambda item: _NAMES[item[0]]):
        out += [f"### `{_NAMES[name]}`", ""]
        if schema.get("description"):
            out += [_cell(schema["description"]), ""]
        props = schema.get("properties", {})
        if props:
            required = set(schema.get("required", []))
            out += ["| Field | Type | Required | Bounds | Description |", "|---|---|---|---|---|"]
            for field, fs in props.items():
                out.append(
                    f"| `{field}` | {_cell(_type(fs))} | {'yes' if field in required else 'no'} | "
                    f"{_cell(_bounds(fs))} | {_cell(fs.get('description', ''))} |"
                )
            out.append("")
        elif "enum" in schema:
            out += ["One of " + ", ".join(f"`{v}`" for v in schema["enum"]) + ".", ""]
    return "\n".join(out) + "\n"


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add the generated OpenAPI document and its reference page to the site."""
    root = Path(config.config_file_path).parent
    spec = openapi_document(root)
    files.append(
        File.generated(config, "reference/openapi.json", content=json.dumps(spec, indent=1))
    )
    files.append(File.generated(config, "reference/http-api.md", content=render(spec)))
    return files
