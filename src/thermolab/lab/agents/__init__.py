"""Remote rigs: the lab's side of ``thermolab agent`` (issue #14).

:mod:`.secrets` issues and checks the per-rig secrets (stored hashed);
:mod:`.hub` serves the rig hosts' WebSocket, stores what they send and
judges their health; :mod:`.runs` carries START, END and inputs to them.
The messages are :mod:`thermolab.agent.protocol`'s, declared once for both ends.
"""

from thermolab.lab.agents.hub import HEALTH_FAULT, AgentHub, HostStatus
from thermolab.lab.agents.runs import RemoteRuns
from thermolab.lab.agents.secrets import check_secret, issue_secret

__all__ = [
    "HEALTH_FAULT",
    "AgentHub",
    "HostStatus",
    "RemoteRuns",
    "check_secret",
    "issue_secret",
]
