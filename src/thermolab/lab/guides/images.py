"""Pictures for guide pages: checked and re-encoded with Pillow before they are stored.

A teacher uploads a photo of the rig or a diagram; :func:`clean_image` accepts
it only if Pillow reads it as PNG, JPEG, GIF or WebP (SVG and every other
format are refused: SVG can carry script, and each other decoder is more code
an upload could reach), with at most :data:`MAX_IMAGE_BYTES` bytes and
:data:`MAX_IMAGE_PIXELS` pixels (checked from the header, before anything is
decoded, so a small file that claims a huge picture is refused without
decoding it). It is then decoded in full and written again in its own format,
which drops its metadata (a phone photo's EXIF with the place it was taken,
XMP, comments): only the pixels, their orientation (applied), the colour
profile and a GIF's or PNG's transparency survive. An animated GIF or WebP
keeps its first frame.

The checks are Pillow's (``Image.open`` restricted to the four formats,
``verify``, ``load``, its decompression-bomb guard); the few lines that choose
what to refuse and keep are hand-written.
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass

from PIL import Image, ImageOps, UnidentifiedImageError

from thermolab.errors import InvalidParameterError

__all__ = [
    "IMAGE_TYPES",
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "CleanImage",
    "ImageInvalidError",
    "ImagePixelsError",
    "ImageTooLargeError",
    "ImageTypeError",
    "clean_image",
]

MAX_IMAGE_BYTES = 2 * 1024 * 1024
"""The largest upload accepted (2 MiB: a phone photo saved for the web, a diagram)."""
MAX_IMAGE_PIXELS = 16_000_000
"""The most pixels a picture may have (a 12-megapixel phone photo, 4032 × 3024, fits);
decoding one takes at most 64 MB of memory."""
IMAGE_TYPES = {"PNG": "image/png", "JPEG": "image/jpeg", "GIF": "image/gif", "WEBP": "image/webp"}
"""The formats accepted (Pillow's names) and the content type each is served with."""


class ImageInvalidError(InvalidParameterError):
    """The upload is not a picture Pillow can read (damaged, or another kind of file)."""


class ImageTypeError(InvalidParameterError):
    """The upload is a picture of a format the guides do not take (SVG, TIFF, BMP...)."""


class ImageTooLargeError(InvalidParameterError):
    """The upload has more than :data:`MAX_IMAGE_BYTES` bytes."""


class ImagePixelsError(InvalidParameterError):
    """The picture has more than :data:`MAX_IMAGE_PIXELS` pixels (a decompression bomb too)."""


@dataclass(frozen=True, slots=True)
class CleanImage:
    """A picture as the lab stores it: re-encoded, without metadata.

    Attributes
    ----------
    data : bytes
    content_type : str
        One of :data:`IMAGE_TYPES`' values.
    width, height : int
        In pixels, after the photo's orientation was applied.
    sha256 : str
        Hex digest of ``data`` (the same picture is stored once per rig).
    """

    data: bytes
    content_type: str
    width: int
    height: int
    sha256: str


def _looks_like_markup(data: bytes) -> bool:
    head = data[:512].lstrip().lower()
    return head.startswith((b"<", b"\xef\xbb\xbf<")) or b"<svg" in head


def _refuse_unreadable(data: bytes, declared: str | None) -> InvalidParameterError:
    allowed = ", ".join(IMAGE_TYPES.values())
    declared = (declared or "").split(";")[0].strip().lower()
    other = declared.startswith("image/") and declared not in IMAGE_TYPES.values()
    if _looks_like_markup(data) or other:
        shown = declared or "markup"
        return ImageTypeError(f"only {allowed} pictures are accepted (this one is {shown})")
    return ImageInvalidError(f"the file is not a picture the lab can read ({allowed})")


def _check_pixels(width: int, height: int) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise ImagePixelsError(
            f"a picture may have at most {MAX_IMAGE_PIXELS} pixels (this one is {width} × {height})"
        )


def _open(data: bytes, declared: str | None) -> Image.Image:
    try:
        image = Image.open(io.BytesIO(data), formats=list(IMAGE_TYPES))
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        # Over Pillow's own limit (a warning only where warnings are made errors).
        raise ImagePixelsError(f"a picture may have at most {MAX_IMAGE_PIXELS} pixels") from exc
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise _refuse_unreadable(data, declared) from exc
    _check_pixels(*image.size)
    return image


def clean_image(data: bytes, declared: str | None = None) -> CleanImage:
    """Check an uploaded picture and re-encode it without its metadata.

    Parameters
    ----------
    data : bytes
        The file as uploaded.
    declared : str, optional
        The content type the browser gave it (only used to say why a file is refused).

    Returns
    -------
    CleanImage

    Raises
    ------
    ImageTooLargeError
        Over :data:`MAX_IMAGE_BYTES`.
    ImageTypeError
        A picture of another format (SVG, BMP, TIFF...).
    ImageInvalidError
        Not a picture, or a damaged one.
    ImagePixelsError
        Over :data:`MAX_IMAGE_PIXELS` pixels.
    """
    if len(data) > MAX_IMAGE_BYTES:
        raise ImageTooLargeError(
            f"a picture may have at most {MAX_IMAGE_BYTES} bytes (2 MiB; this one has "
            f"{len(data)}): save it smaller or in JPEG"
        )
    image = _open(data, declared)
    kind = image.format or ""
    try:
        image.verify()  # the structure (PNG chunks' checksums...) before decoding
        image = _open(data, declared)
        image.seek(0)
        image.load()
        image = ImageOps.exif_transpose(image)  # as the phone showed it, before EXIF goes
    except (OSError, ValueError, SyntaxError, EOFError) as exc:
        raise ImageInvalidError(f"the picture is damaged or cut short ({exc})") from exc
    _check_pixels(*image.size)
    return _encode(image, kind)


def _encode(image: Image.Image, kind: str) -> CleanImage:
    keep: dict[str | tuple[int, int], object] = {
        k: image.info[k] for k in ("transparency",) if k in image.info
    }
    profile = image.info.get("icc_profile")
    image.info = keep
    options: dict[str, object] = {}
    if profile:
        options["icc_profile"] = profile  # colours, not personal data
    if kind == "JPEG":
        if image.mode not in ("L", "RGB", "CMYK"):
            image = image.convert("RGB")
        options.update(quality=90, optimize=True)
    elif kind == "WEBP":
        options.update(quality=90)
    elif kind == "GIF" and image.mode not in ("P", "L"):
        image = image.convert("P")
    out = io.BytesIO()
    image.save(out, kind, **options)
    data = out.getvalue()
    return CleanImage(
        data, IMAGE_TYPES[kind], image.width, image.height, hashlib.sha256(data).hexdigest()
    )
