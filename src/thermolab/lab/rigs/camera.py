"""The live image of a rig (``GET /api/rigs/{rig}/camera``).

A real rig has a camera: a URL that answers with a JPEG (a snapshot) or an
MJPEG stream, of which the first frame is taken. A digital twin has none, so
its picture is drawn from its state: the box, the lamp glowing with the
heating power (positive input), the fan turning with the cooling (negative
input), and the output reading. Pictures are cached for a moment, so that a
class of watchers polling the image costs one drawing, not one each.
"""

from __future__ import annotations

import importlib.util
import io
import math
import threading
import time
import unicodedata
import urllib.request
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

from thermolab.errors import RigError
from thermolab.records import unit_symbol

__all__ = [
    "CAMERA_WORDS",
    "CameraError",
    "Picture",
    "PictureCache",
    "draw_twin",
    "fetch_camera",
    "first_jpeg",
    "picture_text",
]

#: The words a twin's picture shows, as gettext msgids (``lab/locale`` translates
#: them): the readings, each rig state, and the title the lab ships its default rig
#: with (``lab.config.model.DEFAULT_RIG``: the lab's own words; an operator's title
#: is shown as written).
CAMERA_WORDS: Mapping[str, str] = {
    "default_title": "Digital twin of the paper's box",
    "output": "output {value} {unit}",
    "input": "input {value} {unit}",
    "off": "off",
    "starting": "starting",
    "free": "free",
    "in_use": "in use",
    "cooldown": "cooling down",
    "fault": "fault",
    "out_of_service": "out of service",
}

WIDTH, HEIGHT = 480, 320
MAX_FRAME = 4 * 1024 * 1024
_SOI, _EOI = b"\xff\xd8", b"\xff\xd9"


class CameraError(RigError):
    """A rig's camera could not be read (unreachable, not a JPEG, too large)."""


@dataclass(frozen=True, slots=True)
class Picture:
    """What a twin's picture shows.

    Attributes
    ----------
    title : str
    state : str
        The rig's state (``in_use``, ``off``...).
    u : float or None
        Input in force (None: unknown).
    y : float or None
        Latest output reading.
    input_min, input_max : float
        The input range (scales the lamp and the fan).
    input_unit, output_unit : str
        As the rig declares them (``degC``); the picture writes them as a person
        reads them (``°C``), a sign Pillow's built-in font has too.
    say : callable
        The words in the reader's language (a gettext function; English by default).
    decimal_mark : str
        The reader's decimal mark ("," in pt-BR and es).
    """

    title: str
    state: str
    u: float | None
    y: float | None
    input_min: float
    input_max: float
    input_unit: str
    output_unit: str
    say: Callable[[str], str] = str
    decimal_mark: str = "."


@cache
def _font_file() -> Path | None:
    """A TrueType font with every letter of Portuguese and Spanish: matplotlib's DejaVu
    Sans when matplotlib is installed (the ``plot`` extra), else none."""
    spec = importlib.util.find_spec("matplotlib")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        path = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if path.is_file():
            return path
    return None


def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    path = _font_file()
    return ImageFont.truetype(str(path), size) if path else ImageFont.load_default(size=size)


def picture_text(text: str) -> str:
    """``text`` as the picture writes it: as is with DejaVu Sans; without its accents
    ("saida") with Pillow's built-in font, which has no accented letter (a box would
    stand in for it).

    Examples
    --------
    >>> picture_text("output 0.785 V")
    'output 0.785 V'
    """
    if _font_file() is not None:
        return text
    decomposed = unicodedata.normalize("NFKD", text)
    return "".join(c for c in decomposed if not unicodedata.combining(c))


def draw_twin(picture: Picture) -> bytes:
    """Draw a twin's state as a JPEG image.

    Examples
    --------
    >>> jpeg = draw_twin(Picture("Twin", "in_use", 10.0, 1.4, -10.0, 10.0, "V", "V"))
    >>> jpeg[:2] == b"\\xff\\xd8", Image.open(io.BytesIO(jpeg)).size
    (True, (480, 320))
    """
    u = picture.u if picture.u is not None and math.isfinite(picture.u) else 0.0
    heat = max(0.0, u) / picture.input_max if picture.input_max > 0 else 0.0
    cool = max(0.0, -u) / -picture.input_min if picture.input_min < 0 else 0.0
    image = Image.new("RGB", (WIDTH, HEIGHT), (24, 28, 36))
    draw = ImageDraw.Draw(image)
    font = _font(18)
    small = _font(14)
    # The wooden box.
    draw.rectangle((60, 70, 420, 270), fill=(133, 94, 66), outline=(90, 60, 40), width=4)
    draw.rectangle((80, 90, 400, 250), fill=(60, 44, 34))
    # The lamp: a bulb whose glow grows with the heating power.
    cx, cy = 170, 170
    glow = int(40 + 70 * min(1.0, heat))
    for radius in range(glow, 24, -6):
        level = (glow - radius) / max(1, glow - 24)
        shade = (int(60 + 195 * heat * level), int(44 + 160 * heat * level), int(34 + 40 * level))
        draw.ellipse((cx - radius, cy - radius, cx + radius, cy + radius), fill=shade)
    bulb = (int(120 + 135 * heat), int(110 + 120 * heat), 60)
    draw.ellipse((cx - 24, cy - 24, cx + 24, cy + 24), fill=bulb, outline=(30, 30, 30), width=2)
    # The fan: blades drawn more spread the faster it turns.
    fx, fy, blade = 320, 170, 50
    draw.ellipse((fx - blade, fy - blade, fx + blade, fy + blade), outline=(160, 170, 180), width=3)
    blades = 3
    spread = 18 + 40 * min(1.0, cool)
    for i in range(blades):
        angle = 2 * math.pi * i / blades
        for side in (-1, 1):
            a = angle + side * math.radians(spread / 2)
            draw.line(
                (fx, fy, fx + blade * math.cos(a), fy + blade * math.sin(a)),
                fill=(120 + int(120 * cool), 180, 220),
                width=4,
            )
    draw.ellipse((fx - 8, fy - 8, fx + 8, fy + 8), fill=(200, 200, 210))
    # The words.
    # No em dash or middle dot (Pillow's built-in font has none); accents: picture_text.
    say, mark = picture.say, picture.decimal_mark
    state = CAMERA_WORDS.get(picture.state)
    title = say(picture.title) if picture.title == CAMERA_WORDS["default_title"] else picture.title
    heading = f"{title} ({say(state) if state else picture.state.replace('_', ' ')})"
    draw.text((16, 14), picture_text(heading), fill=(235, 235, 235), font=font)
    # The output to the millivolt, the input to 10 mV: what the box's converters resolve.
    reading = "-" if picture.y is None or not math.isfinite(picture.y) else f"{picture.y:.3f}"
    output = say(CAMERA_WORDS["output"])
    output = output.format(value=reading.replace(".", mark), unit=unit_symbol(picture.output_unit))
    draw.text((16, 286), picture_text(output), fill=(255, 220, 120), font=font)
    shown = "-" if picture.u is None else f"{u:+.2f}".replace(".", mark)
    words = say(CAMERA_WORDS["input"]).format(value=shown, unit=unit_symbol(picture.input_unit))
    draw.text((300, 290), picture_text(words), fill=(170, 210, 255), font=small)
    out = io.BytesIO()
    image.save(out, format="JPEG", quality=80)
    return out.getvalue()


def first_jpeg(data: bytes) -> bytes:
    """Return the first complete JPEG in ``data`` (a JPEG itself, or an MJPEG stream).

    Raises
    ------
    CameraError
        If there is no complete JPEG.

    Examples
    --------
    >>> part = b"--frame\\r\\nContent-Type: image/jpeg\\r\\n\\r\\n"
    >>> stream = part + b"\\xff\\xd8abc\\xff\\xd9\\r\\n--frame"
    >>> first_jpeg(stream)
    b'\\xff\\xd8abc\\xff\\xd9'
    """
    start = data.find(_SOI)
    end = data.find(_EOI, start + 2) if start >= 0 else -1
    if start < 0 or end < 0:
        raise CameraError("the camera sent no complete JPEG image")
    return data[start : end + 2]


def fetch_camera(url: str, *, timeout: float = 3.0) -> bytes:
    """Read one JPEG from a camera URL (snapshot or MJPEG stream).

    Raises
    ------
    CameraError
        If the camera cannot be reached in ``timeout`` seconds or sends no JPEG.
    """
    if not url.startswith(("http://", "https://")):
        raise CameraError(
            f"camera {url!r} is not supported: give an http(s) URL of a JPEG or MJPEG camera"
        )
    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            data = b""
            while len(data) < MAX_FRAME:
                chunk = response.read(65536)
                if not chunk:
                    break
                data += chunk
                start = data.find(_SOI)
                if start >= 0 and data.find(_EOI, start + 2) >= 0:
                    break
    except OSError as exc:
        raise CameraError(f"camera {url} unreachable: {exc}") from None
    return first_jpeg(data)


class PictureCache:
    """The latest picture of each rig, kept for ``ttl`` seconds of real time.

    Parameters
    ----------
    ttl : float
        Seconds a picture is served again before a new one is made.
    """

    def __init__(self, ttl: float = 0.5) -> None:
        self._ttl = ttl
        self._pictures: dict[str, tuple[float, bytes]] = {}
        self._lock = threading.Lock()

    def get(self, key: str, make: Callable[[], bytes]) -> bytes:
        """Return the cached picture of ``key``, or ``make()`` a new one."""
        now = time.monotonic()
        with self._lock:
            cached = self._pictures.get(key)
            if cached is not None and now - cached[0] < self._ttl:
                return cached[1]
        picture = make()
        with self._lock:
            self._pictures[key] = (now, picture)
        return picture
