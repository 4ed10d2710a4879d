"""Checks of the interface's files that need no browser.

The interface must work with no internet access and no build step: every file
a page or module refers to is in the package, nothing is loaded from another
site, and the vendored chart library ships with its licence and version note.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from thermolab.web import STATIC_DIR

JS_FILES = sorted((STATIC_DIR / "js").rglob("*.js"))
# Static imports and `export ... from` (statements at the start of a line), and dynamic imports.
IMPORT = re.compile(
    r"""^\s*(?:import|export)\b[^;]*?\bfrom\s*["']([^"']+)["']"""
    r"""|^\s*import\s*["']([^"']+)["']"""
    r"""|\bimport\(\s*["']([^"']+)["']\s*\)""",
    re.MULTILINE,
)


def test_static_dir_is_a_folder_with_the_entry_page() -> None:
    assert isinstance(STATIC_DIR, Path)
    assert (STATIC_DIR / "index.html").is_file()
    assert JS_FILES, "no JavaScript modules found"


def test_index_refers_only_to_files_in_the_package() -> None:
    html = (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    refs = re.findall(r"""(?:src|href)="([^"#][^"]*)\"""", html)
    local = [r for r in refs if not r.startswith("data:")]
    assert local, "index.html refers to no files"
    for ref in local:
        assert "://" not in ref, f"external reference {ref}"
        assert not ref.startswith("//"), f"external reference {ref}"
        assert (STATIC_DIR / ref).is_file(), f"index.html refers to a missing file {ref}"


@pytest.mark.parametrize("path", JS_FILES, ids=lambda p: p.relative_to(STATIC_DIR).as_posix())
def test_module_imports_resolve_to_files_in_the_package(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    specs = [next(g for g in groups if g) for groups in IMPORT.findall(text)]
    for spec in specs:
        assert spec.startswith(("./", "../", "/")), f"{path.name}: bare or external import {spec}"
        target = (STATIC_DIR / spec.lstrip("/")) if spec.startswith("/") else (path.parent / spec)
        assert target.resolve().is_file(), f"{path.name}: import {spec} does not exist"


def test_the_import_pattern_sees_static_and_dynamic_imports() -> None:
    text = (STATIC_DIR / "js" / "app.js").read_text(encoding="utf-8")
    specs = {next(g for g in groups if g) for groups in IMPORT.findall(text)}
    assert {"./api.js", "./views/rig.js"} <= specs


def test_no_file_loads_anything_from_another_site() -> None:
    own = [*JS_FILES, STATIC_DIR / "index.html", *(STATIC_DIR / "css").glob("*.css")]
    pattern = re.compile(r"""(?:src|href|url\(|fetch\(|import\(?)\s*=?\s*["']?(https?:)?//""")
    for path in own:
        text = path.read_text(encoding="utf-8")
        assert not pattern.search(text), f"{path.name} refers to another site"


def test_vendored_uplot_ships_with_its_licence_and_version() -> None:
    vendor = STATIC_DIR / "vendor" / "uplot"
    licence = (vendor / "LICENSE").read_text(encoding="utf-8")
    assert "MIT License" in licence
    assert "Leon Sorokin" in licence
    note = (vendor / "README.md").read_text(encoding="utf-8")
    version = re.search(r"uPlot (\d+\.\d+\.\d+)", note)
    assert version, "the vendor note must say which uPlot version is shipped"
    head = (vendor / "uPlot.esm.js").read_text(encoding="utf-8")[:400]
    assert "uPlot" in head
    assert f"v{version.group(1)}" in head, "the vendor note's version differs from the file's"
    assert (vendor / "uPlot.min.css").is_file()


def test_static_files_are_declared_as_package_data() -> None:
    import tomllib

    root = Path(__file__).resolve().parents[2]
    pyproject = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    package_data = pyproject["tool"]["setuptools"]["package-data"]["thermolab"]
    assert "web/static/**/*" in package_data


def test_every_module_is_type_checked() -> None:
    """Each module opts in to TypeScript's checks, and tsconfig.json covers them all."""
    unchecked = [
        p.relative_to(STATIC_DIR).as_posix()
        for p in (STATIC_DIR / "js").rglob("*.js")
        if not p.read_text(encoding="utf-8").startswith("// @ts-check\n")
    ]
    assert unchecked == []
    root = Path(__file__).resolve().parents[2]
    config = (root / "tsconfig.json").read_text(encoding="utf-8")
    assert '"checkJs": true' in config
    assert '"src/thermolab/web/static/js/**/*.js"' in config
    # The vendored uPlot is typed by a declaration beside it, not checked itself.
    assert (STATIC_DIR / "vendor" / "uplot" / "uPlot.esm.d.ts").is_file()
