"""The login throttle and live-socket counts shared by a fleet's workers in Redis.

(:mod:`thermolab.lab.fleet.shared_limits`; real processes: test_workers_limits.py.)
Two throttles on one real Redis stand for two web workers: failures on one
delay logins on the other, an address's attempts on both count together, the
waits end when the rules say (the same as the in-memory throttle's, checked
step by step against it), and a throttle whose Redis is unreachable falls
back to its own worker's counts. The LTI login initiations alike: 30 a
minute per address over both workers, one's own count without Redis. Two
workers' socket counts see each other's and stop counting when one closes or
stops refreshing. Skipped, with the
reason, without Redis.
"""

from __future__ import annotations

import random
import time
from typing import Any

import pytest

from thermolab.lab.accounts.security import LoginThrottle, RateLimitedError
from thermolab.lab.clock import ManualClock
from thermolab.lab.fleet.shared_limits import (
    SharedInitiationRate,
    SharedLiveSocketCounts,
    SharedLoginThrottle,
)
from thermolab.lab.fleet.worker_hashes import figures_client
from thermolab.lab.lti.errors import LtiThrottledError
from thermolab.lab.lti.launch import InitiationRate

pytestmark = pytest.mark.redis

NUMBERS: dict[str, Any] = {"failures_per_user": 2, "attempts_per_address": 5, "window": 60.0}


def two_workers(
    redis: Any, prefix: str, clock: ManualClock, **numbers: Any
) -> tuple[LoginThrottle, LoginThrottle]:
    numbers = {**NUMBERS, **numbers}
    return (
        SharedLoginThrottle(redis, prefix, clock, **numbers),
        SharedLoginThrottle(redis, prefix, clock, **numbers),
    )


def fail(throttle: LoginThrottle, name: str, address: str) -> None:
    throttle.check(name, address)
    throttle.record(name, address, success=False)


def test_failures_on_one_worker_delay_the_next_login_on_the_other(redis: Any, prefix: str) -> None:
    clock = ManualClock()
    first, second = two_workers(redis, prefix, clock, attempts_per_address=1000)
    fail(first, "tina", "10.0.0.1")
    fail(second, "tina", "10.0.0.1")
    fail(first, "tina", "10.0.0.1")  # the third: one past the two free ones
    with pytest.raises(RateLimitedError, match="too many failed logins for 'tina'") as info:
        second.check("tina", "10.0.0.1")
    assert info.value.retry_after == pytest.approx(1.0)
    second.check("tina", "10.0.0.2")  # another address is not delayed
    second.check("ana", "10.0.0.1")  # nor another name
    clock.advance(1)
    second.check("tina", "10.0.0.1")
    fail(second, "tina", "10.0.0.1")  # the fourth doubles the wait, on both
    with pytest.raises(RateLimitedError) as info:
        first.check("tina", "10.0.0.1")
    assert info.value.retry_after == pytest.approx(2.0)
    clock.advance(2)
    first.check("tina", "10.0.0.1")
    # A success on one worker forgets the pair's failures on every worker.
    first.record("tina", "10.0.0.1", success=True)
    fail(second, "tina", "10.0.0.1")
    second.check("tina", "10.0.0.1")


def test_an_addresss_attempts_on_both_workers_count_until_the_window_has_passed(
    redis: Any, prefix: str
) -> None:
    clock = ManualClock()
    first, second = two_workers(redis, prefix, clock)
    for i in range(5):  # five accounts tried, alternately on each worker
        worker = (first, second)[i % 2]
        worker.check(f"user{i}", "10.0.0.9")
        worker.record(f"user{i}", "10.0.0.9", success=i == 4)
        clock.advance(1)
    for worker in (first, second):
        with pytest.raises(
            RateLimitedError, match=r"too many login attempts from 10\.0\.0\.9"
        ) as info:
            worker.check("someone", "10.0.0.9")
        assert info.value.retry_after == pytest.approx(55.0)  # the first attempt's window
    first.check("someone", "10.0.0.8")
    clock.advance(54.5)
    with pytest.raises(RateLimitedError):
        second.check("someone", "10.0.0.9")
    clock.advance(0.5)  # the first attempt is out of the window: one place free
    second.check("someone", "10.0.0.9")


def test_the_longest_delay_is_the_window_and_failures_are_forgotten_after_15_minutes(
    redis: Any, prefix: str
) -> None:
    clock = ManualClock()
    first, second = two_workers(redis, prefix, clock, attempts_per_address=1000)
    for _ in range(20):
        first.record("tina", "10.0.0.1", success=False)
    with pytest.raises(RateLimitedError) as info:
        second.check("tina", "10.0.0.1")
    assert info.value.retry_after == pytest.approx(60.0)
    clock.advance(60)
    second.check("tina", "10.0.0.1")
    # Fifteen minutes after the last failure, the count starts again: one failure is free.
    clock.advance(15 * 60 - 60)
    fail(second, "tina", "10.0.0.1")
    first.check("tina", "10.0.0.1")


def outcome(throttle: LoginThrottle, name: str, address: str) -> float | None:
    try:
        throttle.check(name, address)
    except RateLimitedError as refused:
        return round(refused.retry_after, 6)
    return None


def test_the_shared_throttle_answers_as_the_in_memory_one_step_by_step(
    redis: Any, prefix: str
) -> None:
    clock = ManualClock()
    memory = LoginThrottle(clock, **NUMBERS)
    workers = two_workers(redis, prefix, clock)
    rng = random.Random(14)
    refused = 0
    for step in range(600):
        name = rng.choice(["tina", "ana", "bo"])
        address = rng.choice(["10.0.0.1", "10.0.0.2"])
        worker = workers[step % 2]
        expected = outcome(memory, name, address)
        assert outcome(worker, name, address) == expected, f"step {step}"
        if expected is None:
            success = rng.random() < 0.2
            memory.record(name, address, success=success)
            worker.record(name, address, success=success)
        else:
            refused += 1
        clock.advance(rng.choice([0.0, 0.5, 1.0, 3.0, 20.0]))
    assert 50 < refused < 550  # both kinds of answer were compared


def test_without_redis_each_worker_throttles_on_its_own_counts() -> None:
    clock = ManualClock()
    # Nothing listens there: every Redis call fails at once.
    unreachable = figures_client("redis://127.0.0.1:1/0")
    throttle = SharedLoginThrottle(unreachable, "thermolab.nowhere.", clock, **NUMBERS)
    for _ in range(3):
        fail(throttle, "tina", "10.0.0.1")
    with pytest.raises(RateLimitedError, match="too many failed logins"):
        throttle.check("tina", "10.0.0.1")  # not unlimited guessing
    throttle.check("ana", "10.0.0.3")  # nor everyone locked out
    clock.advance(1)
    throttle.check("tina", "10.0.0.1")


def test_lti_login_initiations_count_on_every_worker_until_the_window_has_passed(
    redis: Any, prefix: str
) -> None:
    clock = ManualClock()
    lone = InitiationRate(clock)
    first, second = (SharedInitiationRate.like(lone, redis, prefix) for _ in range(2))
    for i in range(30):  # thirty initiations, alternately on each worker
        (first, second)[i % 2].check("10.0.0.9")
        clock.advance(1)
    for worker in (first, second):
        with pytest.raises(LtiThrottledError, match=r"too many LTI logins from 10\.0\.0\.9"):
            worker.check("10.0.0.9")
    first.check("10.0.0.8")  # another address has its own count
    lone.check("10.0.0.9")  # a lone server's count is its own (another lab's here)
    clock.advance(30)  # the first initiation leaves the window: one place, for one worker
    second.check("10.0.0.9")
    with pytest.raises(LtiThrottledError):
        first.check("10.0.0.9")


def test_without_redis_each_worker_counts_its_own_lti_login_initiations() -> None:
    clock = ManualClock()
    unreachable = figures_client("redis://127.0.0.1:1/0")
    rate = SharedInitiationRate(unreachable, "thermolab.nowhere.", clock, per_address=3)
    for _ in range(3):
        rate.check("10.0.0.1")
    with pytest.raises(LtiThrottledError):
        rate.check("10.0.0.1")  # not unlimited
    rate.check("10.0.0.2")  # nor everyone refused


def until(condition: Any, within: float) -> float:
    start = time.monotonic()
    while not condition():
        assert time.monotonic() - start < within, "not in time"
        time.sleep(0.02)
    return time.monotonic() - start


def test_each_worker_counts_the_others_sockets_until_they_close_or_stop_refreshing(
    redis: Any, prefix: str
) -> None:
    first = SharedLiveSocketCounts(redis, prefix, refresh=0.2, ttl=1.0)
    second = SharedLiveSocketCounts(redis, prefix, refresh=0.2, ttl=1.0)
    third = SharedLiveSocketCounts(redis, prefix, refresh=0.2, ttl=1.0)
    ana, bo = ("session", 1), ("session", 2)
    try:
        first.add(ana, "twin")
        first.add(bo, "twin")
        second.add(ana, "other")
        # Published at once after a change (not at the next refresh).
        assert until(lambda: third.others(ana, "twin") == (2, 2), within=0.5) < 0.5
        assert first.others(ana, "twin") == (1, 0)  # not its own
        assert first.here(ana, "twin") == (1, 2)
        first.remove(bo, "twin")
        until(lambda: third.others(ana, "twin") == (2, 1), within=0.5)
        second.close()  # a worker that stops cleanly takes its counts out at once
        assert third.others(ana, "twin") == (1, 1)
        # A worker that stops refreshing (killed) stops counting when its hash expires.
        first.published.halt()
        assert third.others(ana, "twin") == (1, 1)
        waited = until(lambda: third.others(ana, "twin") == (0, 0), within=3.0)
        assert waited > 0.3
        assert redis.sismember(prefix + "live.workers", first.published.worker) == 0  # forgotten
    finally:
        for counts in (first, second, third):
            counts.close()


def test_without_redis_each_worker_counts_only_its_own_sockets() -> None:
    counts = SharedLiveSocketCounts(figures_client("redis://127.0.0.1:1/0"), "thermolab.x.")
    try:
        counts.add(("session", 1), "twin")
        assert counts.others(("session", 1), "twin") == (0, 0)
        assert counts.here(("session", 1), "twin") == (1, 1)
    finally:
        counts.close()
