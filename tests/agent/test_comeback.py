"""A rig host is linked again within 2 s of its network returning (agent/link.py).

Real processes: a TLS lab, and ``thermolab agent`` in a network namespace of
its own whose cable (the lab's end of the veth pair) is pulled with ``ip link
set … down`` for long enough that a doubling back-off would have grown to its
10 s ceiling, then plugged back. The host must not wait out a back-off grown
while the network was away: it probes the lab's address and dials as soon as
it answers. (Skipped with the reason where ``ip netns`` is not permitted.)
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import pytest

from .fleet import ONE_REMOTE_BOX, NetNs, make_fleet

pytestmark = pytest.mark.slow

CUT = 16.0
"""Seconds the cable is out: 0.5 + 1 + 2 + 4 + 8 s of back-off, dials included, fit in it."""


def test_the_host_is_linked_again_within_2_s_of_its_cable_returning(tmp_path: Path) -> None:
    why = NetNs.permitted()
    if why is not None:
        pytest.skip(why)
    ns = NetNs()
    fleet = make_fleet(tmp_path, ONE_REMOTE_BOX, extra_ip=ns.lab_ip)
    try:
        ns.make()
        fleet.start_lab(fleet.cert, fleet.key, grace=30.0, agent_host=ns.lab_ip)  # type: ignore[attr-defined]
        fleet.start_agent("box", "sim:tclab", netns=ns.name)
        with contextlib.closing(fleet.client("tina")) as teacher:
            fleet.wait_online(teacher, "box")
            ns.cut()
            cut_at = time.monotonic()
            while fleet.host(teacher, "box")["online"]:  # the lab notices the silence
                assert time.monotonic() - cut_at < 15, "the lab did not notice the cut"
                time.sleep(0.1)
            time.sleep(max(0.0, CUT - (time.monotonic() - cut_at)))
            ns.mend()
            back = fleet.wait_online(teacher, "box", timeout=30)
            assert back < 2.0, f"linked again {back:.2f} s after the cable returned"
        log = (fleet.data_dir / "agent-box.log").read_text(errors="replace")
        assert "answers again: dialling it" in log, log
    finally:
        fleet.stop()
        ns.remove()
