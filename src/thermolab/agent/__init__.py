"""``thermolab agent``: a rig host that dials its lab.

The rig host owns its rig, the experiment runner and the interlocks
(:mod:`.host`), keeps every sample in a durable outbox until the lab has
it (:mod:`.outbox`), and connects out to the lab over a WebSocket with TLS
(:mod:`.link`); nothing listens on the rig host. :mod:`.protocol` declares
the messages both ends speak: the lab imports it, and this package never
imports the lab (the layer contract in ``pyproject.toml``).
"""

from thermolab.agent.host import RigHost
from thermolab.agent.link import AgentLink, LinkSettings, RefusedError
from thermolab.agent.outbox import Outbox

__all__ = ["AgentLink", "LinkSettings", "Outbox", "RefusedError", "RigHost"]
