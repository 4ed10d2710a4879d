"""Remote rigs: the lab's side of ``thermolab agent`` (issue #14).

:mod:`.secrets` issues and checks the per-rig secrets (stored hashed);
:mod:`.hub` serves the rig hosts' WebSocket, stores what they send and
judges their health (the rule: :mod:`.health`); :mod:`.runs` carries START, END and inputs to them.
The messages are :mod:`thermolab.agent.protocol`'s, declared once for both ends.

How a remote run goes. START on a remote rig is planned and stored by the same
functions as an in-process one (``plan_start``, ``store_start``), then sent to
the host as ``StartRun``; the host's ``Experiment`` samples the rig with its own
interlocks and watchdog. Each sample goes to the host's outbox first, then in
``SampleBatch``es to the lab, which stores them idempotently (``INSERT ... ON
CONFLICT DO NOTHING`` on ``(run_id, k)``) and only then answers ``Ack(seq)``; the
host forgets only what is acknowledged, so a lost link costs a resend, never a
sample. The identification runs in the lab (:mod:`.estimates`), fed the stored
samples in ``k`` order; a closed loop runs on the host, its commands checked here
first (:mod:`.loop`). A run's end on the host leaves the rig off; the lab powers
it on again at its safe input.

Health (:meth:`AgentHub.check`, every sweep): a host away (not connected, or
silent) for longer than its grace (``--agent-grace``, 30 s: the same grace its
run has on the host — one rule), reporting a fault, or reading outside the
rig's output limit puts a fault beginning ``rig host:`` on its rig through the
access model (the turn ends, control is refused, teachers see it, a mail goes
out when configured); the same check clears that fault when the host is healthy
again. A host that redials within its grace keeps its rig, the controller's
turn and its run. Secrets are 256 random bits stored as SHA-256 and compared with
``hmac.compare_digest``; a wrong or rotated secret, an unknown rig or another
protocol version is closed with 4401, and a second host for a rig replaces the
first. User-facing set-up: ``docs/operator.md``, "Rigs on their own computers".
"""

from thermolab.lab.agents.health import HEALTH_FAULT, HostStatus
from thermolab.lab.agents.hub import AgentHub
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
