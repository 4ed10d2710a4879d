"""Closed-loop runs in the lab: what START asks of the controller, and its one check.

Declared in the runner (:mod:`thermolab.runner.control_request`), where a rig
host builds a remote rig's loop from the same request; re-exported here for
the lab's modules.
"""

from __future__ import annotations

from thermolab.rigs import PRIMARY_PAIR
from thermolab.runner.control_request import CONTROL_MODES, ControlRequest, build_control_loop

__all__ = ["CONTROL_MODES", "PRIMARY_PAIR", "ControlRequest", "build_control_loop"]
