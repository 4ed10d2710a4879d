"""Routes of the guide pages' pictures: upload and list (teachers), serve (anyone logged in).

``POST /api/rigs/{rig}/guide-images`` takes a multipart form (``file``, and
``alt``, the picture's text for who cannot see it) and answers the stored
picture with its URL and a Markdown snippet to paste in a section: 201 for a
new picture, 200 when the same picture was already stored for the rig.
``GET /api/guide-images/{id}`` serves the bytes with their content type, an
ETag (the SHA-256) and a year-long ``immutable`` cache (a picture's row never
changes); ``X-Content-Type-Options: nosniff`` comes with every answer
(:mod:`~thermolab.lab.http.browser_guard`). Refusals: 403 ``access_denied``
(a student), 404 ``not_found``, 413 ``image_too_large``, 415
``image_type_unsupported`` (SVG...), 422 ``image_invalid`` and
``image_too_many_pixels`` (:mod:`thermolab.lab.guides.images`).

The path is ``guide-images`` beside ``guide-revisions``, not ``guide/images``:
``PUT /api/rigs/{rig}/guide/{section}`` would claim that path's other methods.
"""

from __future__ import annotations

import re
from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, File, Form, Path, Request, Response, UploadFile, status
from pydantic import Field

from thermolab.lab.guides import (
    IMAGE_TYPES,
    IMAGE_URL,
    MAX_ALT_CHARS,
    MAX_IMAGE_BYTES,
    ImageInfo,
)
from thermolab.lab.http.bodies import Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    RigId,
    UserDep,
    documented_errors,
)
from thermolab.lab.http.limits import BodyAllowance

__all__ = ["CACHEABLE_PREFIX", "UPLOAD_ALLOWANCE", "router"]

router = APIRouter(**AUTHENTICATED)

_FORM_SLACK = 16 * 1024  # the form's boundaries, part headers and the alt text
UPLOAD_ALLOWANCE = BodyAllowance(
    "POST", re.compile(r"/api/rigs/[^/]+/guide-images"), MAX_IMAGE_BYTES + _FORM_SLACK,
    "image_too_large",
)  # fmt: skip
"""The upload's body limit (the lab's other bodies stay under ``access.max_body_bytes``)."""
CACHEABLE_PREFIX = IMAGE_URL.split("{")[0]
"""Answers under this path keep their own ``Cache-Control`` (the pictures)."""
_CACHE = "private, max-age=31536000, immutable"  # a login is needed: no shared cache

ImageId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="a picture's number")]


class ImageOut(Out):
    """A stored picture of a rig's guide (without its bytes)."""

    id: int
    rig: str
    url: str = Field(description="where the picture is served")
    markdown: str = Field(description="the Markdown that shows it, to paste in a section")
    content_type: str
    size: int = Field(description="bytes, as stored (re-encoded, without metadata)")
    width: int
    height: int
    sha256: str
    uploaded_by: str
    uploaded_at: datetime

    @classmethod
    def of(cls, info: ImageInfo, alt: str = "") -> ImageOut:
        """Build from an :class:`~thermolab.lab.guides.ImageInfo`."""
        return cls(
            id=info.id,
            rig=info.rig_id,
            url=info.url,
            markdown=info.markdown(alt),
            content_type=info.content_type,
            size=info.size,
            width=info.width,
            height=info.height,
            sha256=info.sha256,
            uploaded_by=info.uploaded_by,
            uploaded_at=info.uploaded_at,
        )


@router.post(
    "/rigs/{rig_id}/guide-images",
    response_model=ImageOut,
    status_code=status.HTTP_201_CREATED,
    tags=["guides"],
    summary="Upload a picture for a rig's guide",
    responses={
        200: {"model": ImageOut, "description": "the same picture was already stored"},
        **documented_errors(403, 404, 413, 415, 422),
    },
)
def upload_image(
    rig_id: RigId,
    file: Annotated[
        UploadFile,
        File(description=f"a PNG, JPEG, GIF or WebP picture of at most {MAX_IMAGE_BYTES} bytes"),
    ],
    who: UserDep,
    lab: LabDep,
    response: Response,
    alt: Annotated[
        str, Form(max_length=MAX_ALT_CHARS, description="the picture's text, for screen readers")
    ] = "",
) -> ImageOut:
    """Check, clean (no metadata) and store a picture for the rig's guide (teachers only)."""
    who.require_teacher("add pictures to a guide")
    data = file.file.read(MAX_IMAGE_BYTES + 1)  # one byte more tells a file that is too large
    info = lab.guide_images.upload(rig_id, data, who, file.content_type)
    if not info.created:
        response.status_code = status.HTTP_200_OK
    return ImageOut.of(info, alt)


@router.get(
    "/rigs/{rig_id}/guide-images",
    response_model=list[ImageOut],
    tags=["guides"],
    summary="A rig's guide pictures",
    responses=documented_errors(403, 404),
)
def list_images(rig_id: RigId, who: UserDep, lab: LabDep) -> list[ImageOut]:
    """The pictures stored for the rig's guide, newest first, to reuse one (teachers only)."""
    return [ImageOut.of(info) for info in lab.guide_images.of_rig(rig_id, who)]


@router.get(
    "/guide-images/{image_id}",
    tags=["guides"],
    summary="A guide picture",
    response_class=Response,
    responses={
        200: {"content": {kind: {} for kind in IMAGE_TYPES.values()}},
        304: {"description": "the picture the ETag named (If-None-Match)"},
        **documented_errors(404),
    },
)
def serve_image(image_id: ImageId, request: Request, lab: LabDep) -> Response:
    """The picture's bytes (anyone logged in, as the guide), cached for good."""
    image = lab.guide_images.get(image_id)
    etag = f'"{image.sha256}"'
    headers = {
        "ETag": etag,
        "Cache-Control": _CACHE,
        "Content-Disposition": f'inline; filename="guide-image-{image_id}"',
    }
    wanted = request.headers.get("if-none-match", "")
    if etag in {tag.strip() for tag in wanted.split(",")} or wanted.strip() == "*":
        return Response(status_code=status.HTTP_304_NOT_MODIFIED, headers=headers)
    return Response(image.data, media_type=image.content_type, headers=headers)
