"""The bus between web workers: in process, and Redis pub/sub on loopback."""

from __future__ import annotations

import threading
import uuid

import pytest

from thermolab.lab.fleet.bus import BusError, LocalBus, open_bus


def test_the_local_bus_delivers_in_order_to_every_subscriber_of_the_topic() -> None:
    bus = open_bus(None)
    assert isinstance(bus, LocalBus)
    assert not bus.shared
    heard: list[tuple[str, bytes]] = []
    bus.subscribe("a", lambda data: heard.append(("first", data)))
    bus.subscribe("a", lambda data: heard.append(("second", data)))
    bus.subscribe("b", lambda data: heard.append(("other", data)))
    bus.publish("a", b"1")
    bus.publish("a", b"2")
    assert heard == [("first", b"1"), ("second", b"1"), ("first", b"2"), ("second", b"2")]


def test_an_unknown_broker_or_an_unreachable_one_is_one_clear_error() -> None:
    with pytest.raises(BusError, match=r"--broker amqp://x: use redis://HOST:PORT/DB"):
        open_bus("amqp://x")
    with pytest.raises(BusError, match=r"cannot reach the broker at redis://127\.0\.0\.1:1/0"):
        open_bus("redis://127.0.0.1:1/0")


@pytest.mark.redis
def test_two_workers_on_redis_hear_each_other_in_order_and_labs_do_not_mix(
    redis_url: str,
) -> None:
    prefix = f"test.{uuid.uuid4().hex[:8]}."
    a = open_bus(redis_url, prefix=prefix)
    b = open_bus(redis_url, prefix=prefix)
    stranger = open_bus(redis_url, prefix=prefix + "other.")
    try:
        assert a.shared
        heard: list[bytes] = []
        done = threading.Event()

        def hear(data: bytes) -> None:
            heard.append(data)
            if len(heard) == 500:
                done.set()

        b.subscribe("live", hear)
        a.subscribe("live", lambda data: None)  # a worker hears its own messages too
        stranger.subscribe("live", lambda data: heard.append(b"stranger"))
        # The subscription is live once one message makes it through.
        probe = threading.Event()
        b.subscribe("probe", lambda data: probe.set())
        while not probe.wait(0.05):
            a.publish("probe", b"?")
        for k in range(500):
            a.publish("live", str(k).encode())
        assert done.wait(10)
        assert heard == [str(k).encode() for k in range(500)]
    finally:
        for bus in (a, b, stranger):
            bus.close()
