"""A rig's live image: its camera's picture, or a twin's state drawn for everyone.

What :meth:`~thermolab.lab.service.Lab.camera` serves; apart from the lab's
wiring because it reads the turns (the state shown) as well as the device, which
:mod:`.rigs.camera` (drawing and fetching alone) may not.
"""

from __future__ import annotations

from thermolab.lab.access import AccessService
from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import LabConfig
from thermolab.lab.db.models import Role
from thermolab.lab.error_messages import decimal_mark, translate
from thermolab.lab.rigs.camera import Picture, PictureCache, draw_twin, fetch_camera
from thermolab.lab.rigs.devices import DeviceHub

__all__ = ["rig_image"]


def rig_image(
    config: LabConfig,
    access: AccessService,
    hub: DeviceHub,
    pictures: PictureCache,
    rig_id: str,
    language: str,
) -> bytes:
    """Return the rig's live image (JPEG), kept in ``pictures`` briefly.

    A rig with a camera: its picture; otherwise the twin's state drawn with its
    words in ``language``.

    Raises
    ------
    NotFoundError
        For an unknown rig.
    CameraError
        If the rig's camera cannot be read.
    """
    cfg = config.rig(rig_id)
    if cfg.camera is not None:
        url = cfg.camera
        return pictures.get(rig_id, lambda: fetch_camera(url))

    def draw() -> bytes:
        snap = access.snapshot(rig_id)
        view = access.render(snap, _VIEWER)
        published = hub.published(rig_id)
        reading = hub.reading(rig_id)
        return draw_twin(
            Picture(
                title=cfg.title,
                state=view.state,
                u=hub.applied(rig_id),
                y=reading[0] if reading is not None else None,
                input_min=published.input_min,
                input_max=published.input_max,
                input_unit=published.input_unit,
                output_unit=published.output_unit,
                say=lambda text: translate(text, language),
                decimal_mark=decimal_mark(language),
            )
        )

    return pictures.get(f"{rig_id}\n{language}", draw)


# Whose eyes the camera picture is drawn for: the state, which is the same for everyone.
_VIEWER = Principal(user_id=-1, username="(camera)", role=Role.TEACHER)
