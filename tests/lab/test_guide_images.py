"""Pictures of the guide pages: upload (teachers), checks and cleaning by Pillow, serving.

On SQLite and PostgreSQL (the ``database_url`` fixture): PNG, JPEG, GIF and
WebP are accepted and re-encoded (a phone photo's EXIF GPS is gone, its
orientation applied); SVG, a file that only claims to be a PNG, a cut one,
an over-size one and a pixel bomb are refused with their codes; the same
picture twice is one row; the served picture has its type, ETag and cache.
"""

from __future__ import annotations

import io
import struct
import zlib
from typing import Any

import pytest
from fastapi.testclient import TestClient
from PIL import ExifTags, Image

from thermolab.lab.guides import MAX_IMAGE_BYTES, ImageInfo, render_markdown

from .conftest import LabFactory
from .test_live import login, make

UPLOAD = "/api/rigs/twin/guide-images"


def picture(kind: str, size: tuple[int, int] = (40, 30), **options: Any) -> bytes:
    image = Image.new("RGB", size, (200, 40, 40))
    image.putpixel((0, 0), (0, 0, 255))  # a corner to tell the orientation by
    out = io.BytesIO()
    image.save(out, kind, **options)
    return out.getvalue()


def phone_photo() -> bytes:
    """A JPEG with EXIF: the camera, GPS coordinates, and 'rotate 90° to show' (6)."""
    exif = Image.Exif()
    exif[ExifTags.Base.Make] = "PhoneMaker"
    exif[ExifTags.Base.Orientation] = 6
    exif[ExifTags.IFD.GPSInfo] = {
        ExifTags.GPS.GPSLatitudeRef: "S",
        ExifTags.GPS.GPSLatitude: (23.0, 33.0, 1.0),
        ExifTags.GPS.GPSLongitudeRef: "W",
        ExifTags.GPS.GPSLongitude: (46.0, 38.0, 2.0),
    }
    return picture("JPEG", (40, 30), exif=exif.tobytes())


def png_header(width: int, height: int) -> bytes:
    """A tiny PNG that claims ``width`` × ``height`` pixels (a decompression bomb's header)."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        crc = zlib.crc32(kind + body)
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    idat = zlib.compress(b"\0" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def upload(
    client: TestClient,
    headers: dict[str, str],
    data: bytes,
    content_type: str = "image/png",
    alt: str = "the rig",
    rig: str = "twin",
) -> Any:
    return client.post(
        f"/api/rigs/{rig}/guide-images",
        headers=headers,
        files={"file": ("picture", data, content_type)},
        data={"alt": alt},
    )


@pytest.fixture
def teacher_and_student(make_lab: LabFactory) -> Any:
    lab, client, _ = make(make_lab)
    with client:
        yield client, login(lab, "tina"), login(lab, "ana")


@pytest.mark.parametrize(
    ("kind", "content_type"),
    [("PNG", "image/png"), ("JPEG", "image/jpeg"), ("GIF", "image/gif"), ("WEBP", "image/webp")],
)
def test_a_teachers_picture_is_stored_once_and_served_to_students(
    teacher_and_student: Any, kind: str, content_type: str
) -> None:
    client, tina, ana = teacher_and_student
    data = picture(kind)
    first = upload(client, tina, data, "application/octet-stream", alt="Rig [front]\nview")
    assert first.status_code == 201, first.text
    body = first.json()
    assert body["contentType"] == content_type
    assert (body["width"], body["height"], body["rig"]) == (40, 30, "twin")
    assert body["uploadedBy"] == "tina"
    assert body["url"] == f"/api/guide-images/{body['id']}"
    assert body["markdown"] == f"![Rig \\[front\\] view]({body['url']})"
    # The same bytes again: the picture already stored, not a copy.
    again = upload(client, tina, data, content_type)
    assert again.status_code == 200, again.text
    assert again.json()["id"] == body["id"]
    listed = client.get(UPLOAD, headers=tina).json()
    assert [image["id"] for image in listed] == [body["id"]]
    # A student reads it with the guide: its type, an ETag, cached for good.
    served = client.get(body["url"], headers=ana)
    assert served.status_code == 200
    assert served.headers["content-type"] == content_type
    assert served.headers["x-content-type-options"] == "nosniff"
    assert served.headers["etag"] == f'"{body["sha256"]}"'
    cache = served.headers["cache-control"]
    assert "immutable" in cache
    assert "max-age=31536000" in cache
    assert "no-store" not in cache
    assert len(served.content) == body["size"]
    with Image.open(io.BytesIO(served.content)) as back:
        assert (back.format, back.size) == (kind, (40, 30))
    unchanged = client.get(body["url"], headers={**ana, "if-none-match": served.headers["etag"]})
    assert unchanged.status_code == 304
    assert unchanged.content == b""
    # The Markdown snippet shows the picture in the guide as the lab renders it.
    html = render_markdown(body["markdown"])
    assert f'src="{body["url"]}"' in html


def test_a_phone_photo_loses_its_gps_and_keeps_its_orientation(teacher_and_student: Any) -> None:
    client, tina, ana = teacher_and_student
    photo = phone_photo()
    with Image.open(io.BytesIO(photo)) as original:  # the test's photo does carry them
        assert original.getexif().get_ifd(ExifTags.IFD.GPSInfo)
    answer = upload(client, tina, photo, "image/jpeg")
    assert answer.status_code == 201, answer.text
    body = answer.json()
    assert (body["width"], body["height"]) == (30, 40)  # turned as the phone showed it
    served = client.get(body["url"], headers=ana).content
    assert b"PhoneMaker" not in served
    assert b"Exif" not in served
    with Image.open(io.BytesIO(served)) as cleaned:
        assert dict(cleaned.getexif()) == {}
        assert "exif" not in cleaned.info
        assert cleaned.size == (30, 40)


def test_the_refusals_are_4xx_with_their_codes(teacher_and_student: Any) -> None:
    client, tina, ana = teacher_and_student
    svg = b'<svg xmlns="http://www.w3.org/2000/svg" onload="alert(1)"><rect/></svg>'
    png = picture("PNG")
    cases = {
        "svg": (upload(client, tina, svg, "image/svg+xml"), 415, "image_type_unsupported"),
        "svg, said png": (upload(client, tina, svg, "image/png"), 415, "image_type_unsupported"),
        "bmp": (upload(client, tina, picture("BMP"), "image/bmp"), 415, "image_type_unsupported"),
        "fake png": (
            upload(client, tina, b"\x89PNG\r\n\x1a\n" + b"not a picture" * 10),
            422,
            "image_invalid",
        ),
        "text": (upload(client, tina, b"hello", "text/plain"), 422, "image_invalid"),
        "cut short": (upload(client, tina, png[: len(png) // 2]), 422, "image_invalid"),
        "too large": (
            upload(client, tina, png + b"\0" * (MAX_IMAGE_BYTES + 1 - len(png))),
            413,
            "image_too_large",
        ),
        "far too large": (
            upload(client, tina, b"\0" * (MAX_IMAGE_BYTES + 100_000)),
            413,
            "image_too_large",
        ),
        "pixels": (upload(client, tina, png_header(5000, 4000)), 422, "image_too_many_pixels"),
        "bomb": (upload(client, tina, png_header(100_000, 100_000)), 422, "image_too_many_pixels"),
        "student": (upload(client, ana, png), 403, "access_denied"),
        "student list": (client.get(UPLOAD, headers=ana), 403, "access_denied"),
        "no rig": (upload(client, tina, png, rig="nowhere"), 404, "not_found"),
        "no picture": (client.get("/api/guide-images/999", headers=ana), 404, "not_found"),
        "no file": (client.post(UPLOAD, headers=tina, data={"alt": "x"}), 422, "invalid_request"),
        "long alt": (upload(client, tina, png, alt="x" * 201), 422, "invalid_request"),
        "stranger": (client.get("/api/guide-images/1"), 401, "not_authenticated"),
    }
    for name, (answer, status, code) in cases.items():
        assert (answer.status_code, answer.json()["code"]) == (status, code), (name, answer.text)
        assert answer.json()["detail"], name
    assert client.get(UPLOAD, headers=tina).json() == []  # nothing refused was stored
    # The sentence comes in the reader's language.
    answer = upload(client, {**tina, "accept-language": "pt-BR"}, svg, "image/svg+xml")
    assert answer.json()["message"] == "Só são aceitas imagens PNG, JPEG, GIF e WebP."


def test_pictures_are_kept_per_rig(teacher_and_student: Any) -> None:
    client, tina, _ = teacher_and_student
    data = picture("PNG")
    here = upload(client, tina, data).json()
    there = upload(client, tina, data, rig="other")
    assert there.status_code == 201
    assert there.json()["id"] != here["id"]
    assert [i["id"] for i in client.get("/api/rigs/other/guide-images", headers=tina).json()] == [
        there.json()["id"]
    ]


def test_the_renderer_keeps_the_labs_picture_urls_and_nothing_unsafe() -> None:
    html = render_markdown(
        "![rig](/api/guide-images/7) ![x](javascript:alert(1)) "
        '<img src="/api/guide-images/8" onerror="alert(2)">'
    )
    assert '<img src="/api/guide-images/7" alt="rig">' in html
    assert '<img src="/api/guide-images/8">' in html
    assert 'src="javascript' not in html  # the refused link stays as text
    assert "onerror" not in html


def test_the_snippet_escapes_the_alt_text() -> None:
    info = ImageInfo(3, "twin", "image/png", 1, 1, 1, "0" * 64, "tina", None)  # type: ignore[arg-type]
    assert info.markdown("a]b\\c [d]\n\te") == "![a\\]b\\\\c \\[d\\] e](/api/guide-images/3)"
    html = render_markdown(info.markdown("a]b [d]"))
    assert 'alt="a]b [d]"' in html


def test_an_upload_sent_in_chunks_is_cut_at_its_allowance(teacher_and_student: Any) -> None:
    client, tina, _ = teacher_and_student
    head = (
        b'--b\r\nContent-Disposition: form-data; name="file"; filename="x.png"\r\n'
        b"Content-Type: image/png\r\n\r\n"
    )
    chunks = iter([head, *([b"\0" * 512 * 1024] * 5), b"\r\n--b--\r\n"])  # no length declared
    answer = client.post(
        UPLOAD,
        headers={**tina, "content-type": "multipart/form-data; boundary=b"},
        content=chunks,
    )
    assert (answer.status_code, answer.json()["code"]) == (413, "image_too_large")
    # Other routes keep the lab's own limit and code.
    other = client.put(
        "/api/rigs/twin/guide/theory",
        headers={**tina, "content-type": "application/json"},
        content=iter([b'{"markdown": "', b"x" * 70_000, b'"}']),
    )
    assert (other.status_code, other.json()["code"]) == (413, "body_too_large")
