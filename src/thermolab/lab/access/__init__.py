"""Who may do what with a rig: turns, queue, limits, teachers' actions.

* :mod:`.rules` — the turn rules as one pure transition table (``next_state``);
* :mod:`.queries` — the SQL of the hot path;
* :mod:`.views` — snapshots and what each user sees;
* :mod:`.transactions` — :class:`RigTransactions`: the rig locked, the rules applied
  (before and after each action), the change told; reading and rendering rigs;
* :mod:`.service` — :class:`AccessService`: the actions (control, queue, inputs,
  teachers, faults), each one locked transaction.
"""

from thermolab.lab.access.service import AccessService
from thermolab.lab.access.transactions import Controlled
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
    "Controlled",
    "QueueSlot",
    "RigMonitor",
    "RigSnapshot",
    "RigView",
]
