"""Each rig kind declares its typical dead time (issue #8 item 4: the live default)."""

from __future__ import annotations

from thermolab.rigs import RigSpec

#: The kit model's θ (benchmarks/bench_fopdt.py fits it on the noise-free twin).
KIT_THETA = 15.9


def test_each_rig_kind_declares_its_typical_dead_time() -> None:
    """Live there is no record to search: the rig's declared dead time is the one to give.
    The kit twin's is its kit model's θ (transport delay and sensor lag) within 5 %."""
    twin = RigSpec.parse("sim:tclab").typical_dead_time
    assert abs(twin / KIT_THETA - 1.0) <= 0.05
    assert RigSpec.parse("sim").typical_dead_time == 0.0
    assert 15.0 <= RigSpec.parse("tclab").typical_dead_time <= 17.0
