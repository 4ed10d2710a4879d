"""The teachers' rig-hosts page: a remote rig's host comes online and goes offline, live (#14)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.browser

CONFIG = """\
title = "ThermoLab hosts"
[[rigs]]
id = "far"
title = "A kit on its own computer"
spec = "sim:tclab"
agent = true
"""


def test_the_hosts_page_shows_a_host_online_then_offline(
    tmp_path: Path, start_lab: Any, context_for: Any, artifacts: Path
) -> None:
    # A host away longer than its grace is a fault: 3 s here, not the default 30 s.
    with start_lab(
        tmp_path, {"hedda": "teacher"}, config=CONFIG, serve_options=("--agent-grace", "3")
    ) as lab:
        context = context_for(lab, "hedda")
        agent = None
        try:
            page = context.new_page()
            page.goto(f"{lab.url}/#/teacher")
            page.click("a[href='#/hosts']")
            row = page.locator("tr[data-host='far']")
            row.wait_for()
            assert page.get_attribute("tr[data-host='far'] td[data-online]", "data-online") == "no"
            assert "offline" in row.inner_text()
            secret = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "thermolab",
                    "--data-dir",
                    str(lab.data_dir),
                    "agent-secret",
                    "far",
                    "--config",
                    str(lab.data_dir / "lab.toml"),
                ],
                capture_output=True,
                text=True,
                check=True,
            ).stdout.strip()
            (tmp_path / "far.secret").write_text(secret)
            agent = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "thermolab",
                    "agent",
                    "--lab",
                    lab.url.replace("http", "ws"),
                    "--rig",
                    "far",
                    "--spec",
                    "sim:tclab",
                    "--secret-file",
                    str(tmp_path / "far.secret"),
                    "--outbox",
                    str(tmp_path / "outbox.sqlite3"),
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            page.wait_for_selector("tr[data-host='far'] td[data-online='yes']", timeout=30_000)
            page.wait_for_selector("tr[data-host='far'] td[data-fault='no']", timeout=30_000)
            assert "sim:tclab" in row.inner_text()
            page.screenshot(path=str(artifacts / "hosts-online.png"), full_page=True)
            agent.terminate()
            agent.wait(20)
            page.wait_for_selector("tr[data-host='far'] td[data-online='no']", timeout=30_000)
            page.wait_for_selector("tr[data-host='far'] td[data-fault='yes']", timeout=30_000)
            assert "offline" in row.inner_text()
        finally:
            if agent is not None and agent.poll() is None:
                agent.kill()
                agent.wait()
            context.close()
