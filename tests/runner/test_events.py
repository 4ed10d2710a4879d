"""The event bus: bounded queues, cutting a subscriber that falls behind, callbacks on threads."""

from __future__ import annotations

import threading
import time

import pytest

from thermolab.errors import InvalidParameterError, SubscriberCutError
from thermolab.runner import (
    Event,
    EventBus,
    FaultEvent,
    RunState,
    SampleEvent,
    StateEvent,
)


def _sample(bus: EventBus, k: int) -> SampleEvent:
    return SampleEvent(bus.next_seq(), k, float(k), float(k), 1.0, 2.0, 0.0, 0.0)


def test_every_subscriber_gets_every_event_in_order() -> None:
    bus = EventBus()
    subs = [bus.subscribe(name=f"s{i}") for i in range(3)]
    for k in range(100):
        bus.publish(_sample(bus, k))
    bus.close()
    for sub in subs:
        events = list(sub)
        assert [e.seq for e in events] == list(range(100))
        assert sub.closed
        assert not sub.cut


def test_a_full_queue_cuts_its_subscriber_only() -> None:
    bus = EventBus()
    slow = bus.subscribe(maxsize=5, name="slow")
    fast = bus.subscribe(maxsize=1000, name="fast")
    for k in range(20):
        bus.publish(_sample(bus, k))
    assert slow.cut
    assert "'slow' fell 5 events behind" in (slow.cut_reason or "")
    assert slow not in bus.subscribers
    assert fast in bus.subscribers
    # The cut subscriber still reads what was queued before the cut, then learns it was cut.
    got = [event.seq for event in slow.drain()]
    assert got == [0, 1, 2, 3, 4]
    with pytest.raises(SubscriberCutError, match="slow"):
        slow.drain()
    assert len(fast.drain()) == 20


def test_close_unsubscribes() -> None:
    bus = EventBus()
    sub = bus.subscribe()
    sub.close()
    assert not bus.active
    bus.publish(_sample(bus, 0))
    assert list(sub) == []


def test_subscribing_to_a_closed_bus_gives_an_ended_stream() -> None:
    bus = EventBus()
    bus.close()
    sub = bus.subscribe()
    assert sub.closed
    assert list(sub) == []


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"maxsize": 0}, "integer >= 1"),
        ({"maxsize": 2.5}, "integer >= 1"),
    ],
)
def test_bad_subscription_parameters(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        EventBus().subscribe(**kwargs)  # type: ignore[arg-type]


def test_a_blocked_consumer_never_blocks_the_publisher() -> None:
    bus = EventBus()
    release = threading.Event()
    seen: list[int] = []

    def blocked(event: Event) -> None:
        seen.append(event.seq)
        release.wait(10.0)

    sub = bus.subscribe_callback(blocked, maxsize=10, name="blocked")
    start = time.perf_counter()
    for k in range(10_000):
        bus.publish(_sample(bus, k))
    elapsed = time.perf_counter() - start
    release.set()
    assert sub.cut
    # 10,000 publishes while the consumer sleeps: nowhere near its 10 s wait.
    assert elapsed < 5.0


def test_callback_receives_events_in_order_on_its_own_thread() -> None:
    bus = EventBus()
    seen: list[tuple[int, str]] = []
    done = threading.Event()

    def record(event: Event) -> None:
        seen.append((event.seq, threading.current_thread().name))
        if isinstance(event, StateEvent):
            done.set()

    bus.subscribe_callback(record, name="rec")
    for k in range(50):
        bus.publish(_sample(bus, k))
    bus.publish(StateEvent(bus.next_seq(), RunState.FINISHED, RunState.ENDING))
    assert done.wait(5.0)
    assert [s for s, _ in seen] == list(range(51))
    assert {name for _, name in seen} == {"thermolab-subscriber-rec"}


def test_a_failing_callback_is_recorded_as_the_bus_failure() -> None:
    bus = EventBus()

    def broken(event: Event) -> None:
        raise ValueError("boom")

    sub = bus.subscribe_callback(broken, name="broken")
    bus.publish(_sample(bus, 0))
    for _ in range(500):
        if bus.failure is not None:
            break
        time.sleep(0.01)
    assert bus.failure is not None
    message, exc = bus.failure
    assert message == "subscriber 'broken' raised ValueError: boom"
    assert isinstance(exc, ValueError)
    assert sub.closed


def test_a_non_fatal_callback_error_only_disconnects() -> None:
    bus = EventBus()

    def broken(event: Event) -> None:
        raise ValueError("boom")

    sub = bus.subscribe_callback(broken, fatal_errors=False)
    bus.publish(_sample(bus, 0))
    for _ in range(500):
        if sub.closed:
            break
        time.sleep(0.01)
    assert sub.closed
    assert bus.failure is None


def test_events_serialise_to_json_ready_dicts() -> None:
    bus = EventBus()
    sample = _sample(bus, 3).to_dict()
    assert list(sample)[:3] == ["kind", "seq", "k"]
    fault = FaultEvent(bus.next_seq(), 3, "interlock", "too hot", fatal=True).to_dict()
    assert fault == {
        "kind": "fault",
        "seq": 1,
        "k": 3,
        "source": "interlock",
        "message": "too hot",
        "fatal": True,
    }
