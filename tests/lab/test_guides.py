"""Guide pages per rig: sanitised rendering, defaults, revisions and restore, permissions."""

from __future__ import annotations

import json
import re

import pytest

from thermolab.lab.clock import ManualClock
from thermolab.lab.guides import SECTIONS, default_markdown, render_markdown
from thermolab.web import STATIC_DIR

from .conftest import LabFactory
from .test_live import login, make

# On SQLite alone: sanitising and revision rules (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only


def catalogue(lang: str) -> dict[str, object]:
    """The interface's messages in ``lang`` (js/messages/<lang>.js holds a JSON object)."""
    text = (STATIC_DIR / "js" / "messages" / f"{lang}.js").read_text(encoding="utf-8")
    data = json.loads(text[text.index("{", text.index("export const")) : text.rindex("}") + 1])
    assert isinstance(data, dict)
    return data


HOSTILE = """# Welcome

<script>alert('x')</script>

<img src="x.png" onerror="alert(1)"> <a href="javascript:alert(2)">js</a>
[click](javascript:alert(3)) [Upper](JaVaScRiPt:alert(4)) <a href="data:text/html,<b>">d</a>
<div onclick="alert(5)" style="color:red">div</div><iframe src="https://evil"></iframe>
<svg onload="alert(6)"></svg> <math><mi href="javascript:alert(7)">x</mi></math>

<img src="data:image/svg+xml;base64,PHN2Zz4=">

![dot](data:image/png;base64,iVBORw0KGgo=) ![box](https://lab.example/box.png)
and $K_S = \\frac{b}{1-a}$
"""


def test_hostile_markdown_renders_no_script_no_handler_no_javascript_url() -> None:
    html = render_markdown(HOSTILE).lower()
    for forbidden in ("<script", "onerror", "onclick", "onload", "<iframe", "<svg", "style="):
        assert forbidden not in html, forbidden
    assert not re.search(r"\son\w+\s*=", html)  # no event handler attribute at all
    urls = re.findall(r"(?:href|src)\s*=\s*\"([^\"]*)\"", html)
    assert urls == [
        "x.png",
        "data:image/png;base64,ivborw0kggo=",
        "https://lab.example/box.png",
    ]  # javascript:/data: lost their href
    assert "alert(3)" in html  # a refused link stays as plain text, visible to the teacher
    assert "<h1>welcome</h1>" in html
    assert '<img src="https://lab.example/box.png" alt="box">' in html
    assert "<math" in html
    assert "<mfrac>" in html


def test_every_shipped_section_exists_in_every_language_and_renders_its_maths() -> None:
    for lang in ("pt-BR", "en", "es"):
        for section in SECTIONS:
            text = default_markdown(lang, section)
            assert text is not None, (lang, section)
            assert text.startswith("# "), (lang, section)
            assert "math-error" not in render_markdown(text), (lang, section)
    theory = render_markdown(default_markdown("en", "theory") or "")
    assert theory.count("<math") >= 10  # eq. 1-4, the LS solution, the WLSM update


@pytest.mark.parametrize("lang", ["pt-BR", "en", "es"])
def test_the_shipped_steps_name_the_buttons_as_the_page_labels_them(lang: str) -> None:
    # The pt-BR guide said START and END where the buttons read INICIAR and ENCERRAR.
    labels = {
        str(catalogue(lang)[key])
        for key in ("panel.start", "panel.end", "loop.start", "loop.end", "loop.use")
    }
    labels.add(str(catalogue(lang)["panel.automatic"]))
    for number in range(1, 5):
        text = default_markdown(lang, f"panel-{number}") or ""
        pressed = re.findall(r"\*\*([^*]+)\*\*", text)
        assert pressed, (lang, number)
        assert set(pressed) <= labels, (lang, number, set(pressed) - labels)


@pytest.mark.parametrize("lang", ["pt-BR", "en"])
def test_a_student_reads_the_default_until_a_teacher_edits_it(
    make_lab: LabFactory, lang: str
) -> None:
    lab, client, _ = make(make_lab)
    with client:
        guide = client.get(f"/api/rigs/twin/guide?lang={lang}", headers=login(lab, "ana"))
        assert guide.status_code == 200, guide.text
        body = guide.json()
        assert [s["section"] for s in body["sections"]] == list(SECTIONS)
        first = body["sections"][0]
        assert first["revisionId"] is None
        assert first["author"] is None
        assert first["markdown"] == default_markdown(lang, "introduction")
        # The student may not edit, see revisions or preview.
        student = login(lab, "ana")
        put = client.put(
            f"/api/rigs/twin/guide/panel-1?lang={lang}", headers=student, json={"markdown": "x"}
        )
        assert put.status_code == 403
        assert put.json()["code"] == "access_denied"
        listed = client.get(f"/api/rigs/twin/guide/panel-1/revisions?lang={lang}", headers=student)
        assert listed.status_code == 403
        preview = client.post("/api/guide-preview", headers=student, json={"markdown": "x"})
        assert preview.status_code == 403
        # The teacher's text reaches the student, for this rig and language only.
        teacher = login(lab, "tina")
        saved = client.put(
            f"/api/rigs/twin/guide/panel-1?lang={lang}",
            headers=teacher,
            json={"markdown": "Step **one** <script>x()</script>"},
        )
        assert saved.status_code == 200, saved.text
        assert saved.json()["author"] == "tina"
        seen = client.get(f"/api/rigs/twin/guide?lang={lang}", headers=student).json()
        panel = next(s for s in seen["sections"] if s["section"] == "panel-1")
        assert panel["html"].strip() == "<p>Step <strong>one</strong> </p>"  # script and body gone
        assert panel["revisionId"] == saved.json()["revisionId"]
        other = "en" if lang == "pt-BR" else "pt-BR"
        untouched = client.get(f"/api/rigs/twin/guide?lang={other}", headers=student).json()
        assert untouched["sections"][2]["revisionId"] is None
        other_rig = client.get(f"/api/rigs/other/guide?lang={lang}", headers=student).json()
        assert other_rig["sections"][2]["revisionId"] is None


def test_revisions_are_kept_with_author_and_time_and_an_older_one_is_restored(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab, client, _ = make(make_lab)
    lab.users.add("tom", "a long enough passphrase 1", "teacher")
    with client:
        tina, tom = login(lab, "tina"), login(lab, "tom")
        url = "/api/rigs/twin/guide/theory?lang=en"
        first = client.put(url, headers=tina, json={"markdown": "first $a$"}).json()
        clock.advance(300.0)
        second = client.put(url, headers=tom, json={"markdown": "second"}).json()
        history = client.get("/api/rigs/twin/guide/theory/revisions?lang=en", headers=tina)
        assert history.status_code == 200
        rows = history.json()
        assert [(r["id"], r["author"]) for r in rows] == [
            (second["revisionId"], "tom"),
            (first["revisionId"], "tina"),
        ]
        assert rows[0]["savedAt"] > rows[1]["savedAt"]
        old = client.get(f"/api/rigs/twin/guide-revisions/{first['revisionId']}", headers=tom)
        assert old.json()["markdown"] == "first $a$"
        assert "<math" in old.json()["html"]
        restored = client.post(
            f"/api/rigs/twin/guide-revisions/{first['revisionId']}/restore", headers=tom
        )
        assert restored.status_code == 200, restored.text
        assert restored.json()["markdown"] == "first $a$"
        now = client.get("/api/rigs/twin/guide?lang=en", headers=login(lab, "ana")).json()
        assert now["sections"][1]["markdown"] == "first $a$"
        assert now["sections"][1]["author"] == "tom"
        rows = client.get("/api/rigs/twin/guide/theory/revisions?lang=en", headers=tina).json()
        assert len(rows) == 3
        assert rows[0]["restoredFrom"] == first["revisionId"]
        # A revision of another rig's guide is not this rig's.
        wrong = client.get(f"/api/rigs/other/guide-revisions/{first['revisionId']}", headers=tom)
        assert wrong.status_code == 404
        assert wrong.json()["code"] == "not_found"


def test_spanish_reads_its_own_text_and_a_teachers_spanish_revision(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        teacher = login(lab, "tina")
        client.put("/api/rigs/twin/guide/school?lang=en", headers=teacher, json={"markdown": "EN"})
        client.put("/api/rigs/twin/guide/theory?lang=es", headers=teacher, json={"markdown": "ES"})
        body = client.get("/api/rigs/twin/guide?lang=es", headers=login(lab, "ana")).json()
        by_section = {s["section"]: s for s in body["sections"]}
        assert body["lang"] == "es"
        assert (by_section["theory"]["lang"], by_section["theory"]["markdown"]) == ("es", "ES")
        # An English revision is not Spanish: the shipped Spanish text stays.
        school = by_section["school"]
        assert (school["lang"], school["markdown"]) == ("es", default_markdown("es", "school"))
        assert by_section["introduction"]["lang"] == "es"
        assert by_section["introduction"]["markdown"].startswith("# Introducción")


def test_bad_requests_are_4xx_with_a_code(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        teacher = login(lab, "tina")
        cases = [
            client.get("/api/rigs/nowhere/guide", headers=teacher),
            client.get("/api/rigs/twin/guide?lang=fr", headers=teacher),
            client.put("/api/rigs/twin/guide/appendix", headers=teacher, json={"markdown": "x"}),
            client.put("/api/rigs/twin/guide/theory", headers=teacher, json={"markdown": 5}),
            client.put(
                "/api/rigs/twin/guide/theory", headers=teacher, json={"markdown": "x" * 30_001}
            ),
            client.put(
                "/api/rigs/twin/guide/theory", headers=teacher, json={"markdown": "x" * 100_001}
            ),
            client.get("/api/rigs/twin/guide-revisions/999", headers=teacher),
            client.post("/api/rigs/twin/guide-revisions/0/restore", headers=teacher),
            client.get("/api/rigs/twin/guide"),
        ]
        for answer in cases:
            assert 400 <= answer.status_code < 500, answer.text
            assert answer.json()["code"]
        assert [a.status_code for a in cases] == [404, 422, 422, 422, 422, 413, 404, 422, 401]
