"""The collector policy (issue #26): full passes walk only what came since, quiet times free it.

Each check runs in a Python process of its own: the policy changes the
process's collector (what is frozen), which a test worker must not inherit.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import gc, json
    from thermolab.lab.operations.collector import CollectorPolicy

    class Socket:  # a joiner's objects: a cycle, as a protocol and its transport make
        def __init__(self):
            self.peer = self
            self.buffers = [bytearray(64) for _ in range(20)]

    quiet = [False]
    policy = CollectorPolicy(lambda: quiet[0], check_every=3600.0)
    policy.start()
    started = gc.get_freeze_count()
    sockets = [Socket() for _ in range(30_000)]  # a storm's survivors
    gc.collect()
    after_pass = gc.get_freeze_count()
    gc.collect()  # the next full pass walks what came since the last: almost nothing
    walked = gc.get_count()
    del sockets  # the storm's sockets close: cycles, left to the collector
    gc.collect()
    frozen_garbage = gc.get_freeze_count()
    busy = policy.thaw_if_due()  # a run is going: no thaw
    quiet[0] = True
    thawed = policy.thaw_if_due()
    print(json.dumps({
        "started": started, "after_pass": after_pass, "frozen_garbage": frozen_garbage,
        "busy": busy, "thawed": thawed, "after_thaw": gc.get_freeze_count(),
        "unfrozen_young": sum(walked), "thaws": policy.thaws,
    }))
    policy.stop()
    """
)


def run_policy() -> dict[str, int]:
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, check=True
    )
    result: dict[str, int] = json.loads(done.stdout)
    return result


def test_survivors_of_a_full_pass_are_frozen_and_freed_when_the_lab_is_quiet() -> None:
    seen = run_policy()
    # A full pass froze the storm's 30 000 sockets (each a few objects): the next pass
    # walks none of them.
    assert seen["after_pass"] >= seen["started"] + 30_000 * 2
    assert seen["unfrozen_young"] < 1_000
    # Closed, their cycles stay frozen (kept) while a run is going ...
    assert seen["frozen_garbage"] >= seen["after_pass"] - 10
    assert seen["busy"] is False
    # ... and are collected once the lab is quiet: what stays frozen is what lives.
    assert seen["thawed"] is True
    assert seen["thaws"] == 1
    assert seen["after_thaw"] < seen["started"] + 5_000
