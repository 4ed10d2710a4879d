"""Who may do what with a rig: turns, queue, limits, teachers' actions.

* :mod:`.rules` — the turn rules as one pure transition table (``next_state``);
* :mod:`.queries` — the SQL of the hot path;
* :mod:`.views` — snapshots and what each user sees;
* :mod:`.service` — :class:`AccessService`, the rules applied in locked transactions.
"""

from thermolab.lab.access.service import AccessService
from thermolab.lab.access.views import (
    AccessView,
    CommandRecord,
    ControlRecord,
    QueueSlot,
    RigMonitor,
    RigSnapshot,
    RigView,
)

__all__ = [
    "AccessService",
    "AccessView",
    "CommandRecord",
    "ControlRecord",
    "QueueSlot",
    "RigMonitor",
    "RigSnapshot",
    "RigView",
]
