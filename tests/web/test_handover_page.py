"""The rig page shows a rig's further actuators (the fan) and their rest (issue #23).

A student runs a closed loop on the twin, turns its disturbance fan to 50 %
(through the API, as a script would), sees it in the "Now" card, ENDs the run
and sees the fan back at its declared 0 %, as the rig the page receives says.
"""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.browser

RIG = "twin-fan"
ROLE = "[data-testid=access-role]"
FAN_SAYS = "(v) => document.querySelector('[data-readout=fan]')?.textContent === v"


def test_the_fan_is_shown_and_back_at_its_default_once_the_run_ends(
    logged_in: Any, lab: Any
) -> None:
    context = logged_in("fran")
    try:
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(f"{lab.url}/#/rig/{RIG}")
        page.wait_for_function(FAN_SAYS, arg="0")  # at rest from the first look
        page.click("button[data-action=ask]")
        page.wait_for_function(
            "sel => document.querySelector(sel)?.dataset.role === 'controller'", arg=ROLE
        )
        call = """async ([method, path, body]) => {
            const r = await fetch(path, {method, headers: {'Content-Type': 'application/json'},
                                         body: body === null ? undefined : JSON.stringify(body)});
            return r.status;
        }"""
        control = {"setpoint": 0.5, "kp": 5.0, "ti": 100.0}
        run = {"dt": 1, "samples": 2000, "methods": ["lsm"], "control": control}
        assert page.evaluate(call, ["POST", f"/api/rigs/{RIG}/runs", run]) == 201
        fan = ["PUT", f"/api/rigs/{RIG}/runs/current/fan", {"percent": 50}]
        assert page.evaluate(call, fan) == 200
        page.wait_for_function(FAN_SAYS, arg="50")
        assert page.evaluate(call, ["POST", f"/api/rigs/{RIG}/runs/current/stop", None]) == 200
        page.wait_for_function(FAN_SAYS, arg="0")
        assert errors == []
    finally:
        context.close()
