"""Guide pages in the browser: a teacher edits panel 1's steps, a student reads them beside it.

In Portuguese (Brazil) and English, against a real ``thermolab serve`` and
Chromium: the teacher's Markdown (with maths and a hostile image) is saved as
a revision, and the student's "Guide" button on panel 1 opens the drawer at
that section, maths drawn as MathML, the handler gone, and no editor. A teacher
inserts a picture at the editor's cursor (an SVG refused with the catalogue's
sentence), saves, and the student's drawer shows it loaded.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from .guide_drawer import open_panel_guide

pytestmark = pytest.mark.browser

RIG = "twin-keys"


@pytest.mark.parametrize(
    ("locale", "lang", "default_heading", "words"),
    [
        ("pt-BR", "pt-BR", "Painel 1", "Passo um do professor"),
        ("en-US", "en", "Panel 1", "The teacher's step one"),
    ],
)
def test_a_teacher_edits_panel_1_guide_and_a_student_sees_it_beside_panel_1(
    logged_in: Any,
    lab: Any,
    artifacts: Path,
    locale: str,
    lang: str,
    default_heading: str,
    words: str,
) -> None:
    hostile = "<img src=x onerror=\"document.title='pwned'\">"
    markdown = f"## {words}\n\n**Ganho** $K_S = \\frac{{b}}{{1-a}}$ {hostile}"
    teacher = logged_in("tess", locale=locale, viewport={"width": 1280, "height": 900})
    student = logged_in("alice", locale=locale, viewport={"width": 1280, "height": 900})
    try:
        page = teacher.new_page()
        revisions: list[tuple[str, int]] = []
        page.on(
            "response",
            lambda r: revisions.append((r.url, r.status)) if "/revisions" in r.url else None,
        )
        # The guide's read is held back: Edit is clicked before the guide has loaded.
        held: list[Any] = []

        def hold(route: Any) -> None:
            held.append(route)

        page.route(f"**/api/rigs/{RIG}/guide?*", hold)
        page.goto(f"{lab.url}/#/rig/{RIG}")
        open_panel_guide(page, loaded=False)
        for _ in range(100):
            if held:
                break
            page.wait_for_timeout(50)
        (read,) = held
        page.click("[data-testid=guide-edit]")
        page.wait_for_timeout(300)
        assert revisions == []  # no revisions asked for before the guide's language is known
        read.continue_()
        page.unroute(f"**/api/rigs/{RIG}/guide?*")
        text = page.locator("[data-testid=guide-text]")
        text.locator("h1").wait_for()
        assert default_heading in text.locator("h1").inner_text()
        source = page.locator("[data-testid=guide-source]")
        source.wait_for()  # the load did not close the editor again
        page.locator("[data-testid=guide-revisions] li").first.wait_for()
        assert default_heading in source.input_value()  # the section's Markdown, once loaded
        ((url, status),) = revisions
        assert (status, f"lang={lang}") == (200, url.rsplit("?", 1)[1])
        page.click(".guide-editor .buttons button:nth-child(3)")  # cancel
        assert page.locator("html").get_attribute("lang") == lang
        page.click("[data-testid=guide-edit]")
        page.fill("[data-testid=guide-source]", markdown)
        page.locator(".guide-editor button").first.click()  # preview, rendered by the server
        page.locator("[data-testid=guide-preview] math").wait_for()
        page.locator(".guide-editor button.primary").click()  # save
        page.locator("[data-testid=guide-text] h2").wait_for()
        assert words in text.inner_text()
        assert "tess" in page.inner_text("[data-testid=guide-meta]")
        page.screenshot(path=str(artifacts / f"guide-editor-{lang}.png"))

        seen = student.new_page()
        seen.goto(f"{lab.url}/#/rig/{RIG}")
        open_panel_guide(seen)
        shown = seen.locator("[data-testid=guide-text]")
        shown.locator("h2").wait_for()
        assert words in shown.inner_text()
        assert shown.locator("math mfrac").count() == 1  # maths as MathML, no script needed
        assert shown.locator("img").get_attribute("onerror") is None
        assert seen.title() != "pwned"
        assert seen.locator("[data-testid=guide-edit]").count() == 0  # students only read
        assert seen.locator("#panel-srm-lsm").is_visible()  # panel 1 stays open beside it
        # The other sections are one click away: the theory, in the same language.
        seen.locator("[data-testid=guide] nav button[data-section=theory]").click()
        assert shown.locator("math").count() >= 10
        seen.screenshot(path=str(artifacts / f"guide-student-{lang}.png"))
    finally:
        teacher.close()
        student.close()


def _png(width: int, height: int) -> bytes:
    import io

    from PIL import Image

    out = io.BytesIO()
    Image.new("RGB", (width, height), (30, 90, 200)).save(out, "PNG")
    return out.getvalue()


def test_a_teacher_inserts_a_picture_and_the_student_sees_it_loaded(
    logged_in: Any, lab: Any, artifacts: Path
) -> None:
    teacher = logged_in("tess", locale="en-US", viewport={"width": 1280, "height": 900})
    student = logged_in("alice", locale="en-US", viewport={"width": 1280, "height": 900})
    try:
        page = teacher.new_page()
        page.goto(f"{lab.url}/#/rig/{RIG}")
        open_panel_guide(page)  # the guide was read
        page.click("[data-testid=guide-edit]")
        source = page.locator("[data-testid=guide-source]")
        source.wait_for()
        status = page.locator("[data-testid=guide] p[role=status]")
        # An SVG is refused, with the catalogue's sentence for the server's code.
        page.set_input_files(
            "[data-testid=guide-image-file]",
            files=[{"name": "x.svg", "mimeType": "image/svg+xml", "buffer": b"<svg></svg>"}],
        )
        page.click("[data-testid=guide-image-insert]")
        page.wait_for_function(
            "() => document.querySelector('[data-testid=guide] p[role=status]').textContent"
            ".includes('Only PNG, JPEG, GIF and WebP')",
            timeout=30_000,
        )
        assert "/api/guide-images/" not in source.input_value()
        # A PNG goes in at the cursor: after the heading line.
        source.fill("# Step response\n\nThe rig:")
        source.evaluate("el => el.setSelectionRange(el.value.length, el.value.length)")
        page.set_input_files(
            "[data-testid=guide-image-file]",
            files=[{"name": "rig.png", "mimeType": "image/png", "buffer": _png(120, 80)}],
        )
        page.fill("[data-testid=guide-image-alt]", "The rig from the front")
        page.click("[data-testid=guide-image-insert]")
        page.wait_for_function(
            "() => document.querySelector('[data-testid=guide-source]').value.includes('/api/')",
            timeout=30_000,
        )
        text = source.input_value()
        assert text.startswith("# Step response\n\nThe rig:![The rig from the front](/api/")
        assert "uploaded" in status.inner_text()
        page.screenshot(path=str(artifacts / "guide-picture-editor.png"))
        page.locator(".guide-editor button.primary").click()  # save
        page.locator("[data-testid=guide-text] img").wait_for()

        seen = student.new_page()
        seen.goto(f"{lab.url}/#/rig/{RIG}")
        open_panel_guide(seen)
        image = seen.locator("[data-testid=guide-text] img")
        image.wait_for()
        assert image.get_attribute("alt") == "The rig from the front"
        seen.wait_for_function(
            "() => document.querySelector('[data-testid=guide-text] img').complete",
            timeout=30_000,
        )
        assert image.evaluate("img => img.naturalWidth") == 120  # it loaded (CSP, cookie)
        seen.screenshot(path=str(artifacts / "guide-picture-student.png"))
    finally:
        teacher.close()
        student.close()
