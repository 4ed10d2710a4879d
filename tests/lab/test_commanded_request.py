"""An adopted rig-host run's loop: its request with the recorded commands folded in, in order.

The standby that takes a closed-loop run over (lab/agents/runs.py, ``adopt``) answers
the loop route from this until the host's first heartbeat tells the loop itself.
"""

from __future__ import annotations

from thermolab.control import PIDGains
from thermolab.lab.agents.loop import commanded_request
from thermolab.runner.control_request import ControlRequest

START = ControlRequest(setpoint=35.0, kp=4.0, ti=140.0)


def test_the_last_of_each_command_wins_and_other_kinds_leave_the_loop() -> None:
    commands = [
        ("setpoint", {"setpoint": 33.0}),
        ("gains", PIDGains(2.0, 90.0, 5.0).to_dict()),
        ("fan", {"percent": 50.0}),
        ("mode", {"mode": "manual", "u": 20.0}),
        ("input", None),
        ("mode", {"mode": "auto", "setpoint": 31.0}),
        ("setpoint", {"setpoint": 30.0}),
    ]
    after = commanded_request(START, commands)
    assert (after.mode, after.setpoint) == ("auto", 30.0)
    assert (after.kp, after.ti, after.td) == (2.0, 90.0, 5.0)
    assert commanded_request(START, commands[:4]).mode == "manual"
    assert commanded_request(START, commands[:4]).setpoint == 33.0
    assert commanded_request(START, commands[:6]).setpoint == 31.0
    # An auto switch without a set point keeps the one in force.
    assert commanded_request(START, [("mode", {"mode": "auto"})]).setpoint == 35.0
    assert commanded_request(START, []) == START
