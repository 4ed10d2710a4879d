"""What the lab tells those that follow it: :class:`LabListener`.

The live stream is one; :class:`~thermolab.lab.service.Lab` calls every one
it was given. The protocol is apart from the lab's wiring: what a listener is
told does not depend on how the services are put together.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Protocol

from thermolab.lab.runs import RunRecord
from thermolab.runner import Event

__all__ = ["LabListener"]


class LabListener(Protocol):
    """Something told about what happens in the lab (the live stream is one).

    Every method is called from a worker thread and must return quickly.
    """

    def access_changed(self, rig_id: str) -> None:
        """The rig's controller, queue, power or state may have changed."""
        ...

    def run_changed(self, rig_id: str, event: str, record: RunRecord) -> None:
        """A run ``"started"`` or ``"ended"``."""
        ...

    def run_event(self, rig_id: str, run_id: int, event: Event) -> None:
        """A runner event of a run (sample, estimate, state, fault)."""
        ...

    def reading(
        self,
        rig_id: str,
        u: float | None,
        y: float,
        at: datetime,
        channels: Mapping[str, float | None] | None = None,
    ) -> None:
        """A reading of a powered rig with no run (the lab's idle monitoring).

        ``channels``: the rig's further channels with it (a kit's ``t2``, ``q2``).
        """
        ...
