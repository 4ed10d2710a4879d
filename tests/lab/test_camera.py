"""The live image: a twin's state drawn, or a real camera's JPEG / MJPEG frame."""

from __future__ import annotations

import http.server
import io
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image, ImageDraw

from thermolab.lab.config import RigConfig
from thermolab.lab.config.model import DEFAULT_RIG
from thermolab.lab.error_messages import decimal_mark, translate
from thermolab.lab.http.app import create_app
from thermolab.lab.rigs import camera
from thermolab.lab.rigs.camera import (
    CAMERA_WORDS,
    Picture,
    PictureCache,
    draw_twin,
    first_jpeg,
    picture_text,
)
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


def brightness(jpeg: bytes, box: tuple[int, int, int, int]) -> float:
    region = Image.open(io.BytesIO(jpeg)).convert("L").crop(box)
    return float(np.asarray(region, dtype=np.float64).mean())


def test_a_twin_is_drawn_from_its_state(make_lab: LabFactory) -> None:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=VirtualClock())

    lab = make_lab(opener=opener)
    lab._pictures = PictureCache(ttl=0)
    lab.users.add("ana", PASSWORD, "student")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        assert client.get("/api/rigs/twin/camera").status_code == 401
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        off = client.get("/api/rigs/twin/camera")
        assert off.headers["content-type"] == "image/jpeg"
        assert off.headers["cache-control"] == "no-store"
        assert Image.open(io.BytesIO(off.content)).size == (480, 320)
        client.post("/api/rigs/twin/control")
        client.put("/api/rigs/twin/input", json={"u": 10.0})
        lamp_on = client.get("/api/rigs/twin/camera").content
        lamp = (150, 150, 190, 190)
        assert brightness(lamp_on, lamp) > brightness(off.content, lamp) + 40
        assert client.get("/api/rigs/nope/camera").status_code == 404


def test_a_twins_picture_speaks_the_readers_language(
    make_lab: LabFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The picture's words in the page's language, with its decimal mark ("output 0.785 V"
    # was English on a Brazilian page).
    drawn: list[str] = []
    text = ImageDraw.ImageDraw.text

    def record(
        self: ImageDraw.ImageDraw, xy: object, words: str, *args: object, **kw: object
    ) -> None:
        drawn.append(words)
        text(self, xy, words, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(ImageDraw.ImageDraw, "text", record)
    lab = make_lab(opener=lambda rig: TwinRig("paper", clock=VirtualClock()))
    lab._pictures = PictureCache(ttl=0)
    lab.users.add("ana", PASSWORD, "student")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        client.post("/api/rigs/twin/control")
        client.put("/api/rigs/twin/input", json={"u": 2.5})
        client.cookies.set("thermolab_lang", "pt-BR")
        assert client.get("/api/rigs/twin/camera").status_code == 200
        assert drawn[0].endswith("(em uso)"), drawn
        assert drawn[1].startswith(picture_text("saída ")), drawn
        assert drawn[1].endswith(" V"), drawn
        assert drawn[2] == "entrada +2,50 V"
        drawn.clear()
        client.cookies.set("thermolab_lang", "es")
        client.get("/api/rigs/twin/camera")
        assert drawn[0].endswith("(en uso)"), drawn
        assert drawn[2] == "entrada +2,50 V", drawn
        drawn.clear()
        client.cookies.set("thermolab_lang", "en")
        client.get("/api/rigs/twin/camera")
        assert drawn[0].endswith("(in use)"), drawn
        assert drawn[2] == "input +2.50 V", drawn
    # A reading in the reader's form: to the millivolt, with the language's decimal mark.
    drawn.clear()
    say = lambda words: translate(words, "pt-BR")  # noqa: E731
    draw_twin(Picture("Twin", "free", 0.0, 0.785, -10, 10, "V", "V", say, decimal_mark("pt-BR")))
    assert drawn == [picture_text(w) for w in ("Twin (livre)", "saída 0,785 V", "entrada +0,00 V")]
    # The title the lab ships its default rig with is the lab's words: translated too.
    assert CAMERA_WORDS["default_title"] == DEFAULT_RIG.title
    drawn.clear()
    draw_twin(Picture(DEFAULT_RIG.title, "free", None, None, -10, 10, "V", "V", say, ","))
    assert drawn[0] == picture_text("Gêmeo digital da caixa do artigo (livre)")


def test_a_kits_picture_writes_degrees_as_a_person_reads_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A kit declares its sensors in "degC" (the API's and the CSV's spelling); its
    # picture, like the rig page's readout, writes "°C".
    drawn: list[str] = []
    text = ImageDraw.ImageDraw.text

    def record(
        self: ImageDraw.ImageDraw, xy: object, words: str, *args: object, **kw: object
    ) -> None:
        drawn.append(words)
        text(self, xy, words, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(ImageDraw.ImageDraw, "text", record)
    draw_twin(Picture("Kit", "in_use", 50.0, 31.25, 0, 100, "%", "degC"))
    assert drawn[1:] == ["output 31.250 °C", "input +50.00 %"]
    monkeypatch.setattr(camera, "_font_file", lambda: None)  # Pillow's own font has "°" too
    drawn.clear()
    draw_twin(Picture("Kit", "in_use", 50.0, 31.25, 0, 100, "%", "degC"))
    assert drawn[1] == "output 31.250 °C"


class _Camera(http.server.BaseHTTPRequestHandler):
    frame = b"\xff\xd8" + b"not really a picture" + b"\xff\xd9"

    def do_GET(self) -> None:
        self.send_response(200)
        if self.path == "/stream":
            self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
            self.end_headers()
            for _ in range(3):
                self.wfile.write(
                    b"--frame\r\nContent-Type: image/jpeg\r\n\r\n" + self.frame + b"\r\n"
                )
        else:
            self.send_header("Content-Type", "image/jpeg")
            self.end_headers()
            self.wfile.write(self.frame)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def camera_url() -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Camera)
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("path", ["/snapshot.jpg", "/stream"])
def test_a_real_rig_shows_its_camera(make_lab: LabFactory, camera_url: str, path: str) -> None:
    lab = make_lab(camera=camera_url + path)
    lab.users.add("ana", PASSWORD, "student")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        response = client.get("/api/rigs/twin/camera")
    assert response.content == _Camera.frame


def test_an_unreachable_camera_is_a_clear_error(make_lab: LabFactory) -> None:
    lab = make_lab(camera="http://127.0.0.1:1/cam.jpg")
    lab.users.add("ana", PASSWORD, "student")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        response = client.get("/api/rigs/twin/camera")
    assert response.status_code == 503
    assert response.json()["detail"].startswith("camera http://127.0.0.1:1/cam.jpg unreachable")


def test_first_jpeg_needs_a_whole_frame() -> None:
    with pytest.raises(Exception, match="no complete JPEG"):
        first_jpeg(b"\xff\xd8 cut short")


def test_without_a_font_for_accents_the_picture_drops_them(monkeypatch: pytest.MonkeyPatch) -> None:
    # Pillow's built-in font has no "í": a box would stand where the letter is.
    monkeypatch.setattr(camera, "_font_file", lambda: None)
    assert picture_text("saída 0,785 V (em uso)") == "saida 0,785 V (em uso)"
    assert picture_text("Gêmeo (enfriándose)") == "Gemeo (enfriandose)"
    jpeg = draw_twin(Picture("Twin", "free", 0.0, 0.785, -10, 10, "V", "V"))
    assert Image.open(io.BytesIO(jpeg)).size == (480, 320)
