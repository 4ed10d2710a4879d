"""The candidate buses' own fan-out, measured alone: one publisher, several subscriber workers.

For each bus, one publisher process sends live messages (the size of a
``sample`` + ``estimate`` pair, ~600 bytes) at ``--rate`` messages a second
for ``--seconds``, and ``--subscribers`` subscriber processes (the other web
workers) receive them; each message carries its send time (the system's
monotonic clock, shared by the processes). Reported per bus: delivered
share, delay p50/p99/max in ms, and the CPU (% of one core) of the publisher,
of the subscribers together and of the broker's own process.

Buses (each skipped, with the reason, when its server or client is absent):

* ``redis``: Redis pub/sub (redis-py, asyncio);
* ``redis-streams``: Redis streams, XADD / XREAD BLOCK per subscriber;
* ``postgres``: PostgreSQL LISTEN/NOTIFY (psycopg 3);
* ``nats``: NATS JetStream (nats-py), a stream on the subject, push consumers.

Usage::

    .venv/bin/python benchmarks/bench_bus.py                       # 1000 msg/s, 4 subscribers
    .venv/bin/python benchmarks/bench_bus.py --rate 5000 --subscribers 4 --seconds 5
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

SCRIPT = str(Path(__file__).resolve())
TICKS = os.sysconf("SC_CLK_TCK")
PAD = "x" * 520  # a sample and an estimate message are ~600 bytes together
REDIS = os.environ.get("THERMOLAB_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")
POSTGRES = os.environ.get("BENCH_POSTGRES_DSN", "postgresql://postgres@127.0.0.1:5432/test")
NATS = os.environ.get("BENCH_NATS_URL", "nats://127.0.0.1:4222")


def cpu_seconds(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / TICKS


def broker_pids(name: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                comm = (entry / "comm").read_text().strip()
            except OSError:
                continue
            if comm.startswith(name):
                found.append(int(entry.name))
    return found


# -- each bus: publish(topic) and subscribe(topic) as async generators ----------------------------


async def redis_pub(topic: str, messages: list[bytes], rate: float) -> None:
    import redis.asyncio as aioredis

    client = aioredis.Redis.from_url(REDIS)
    await paced(messages, rate, lambda m: client.publish(topic, m))
    await client.aclose()


async def redis_sub(topic: str, ready: Any, count: int, seconds: float) -> list[float]:
    import redis.asyncio as aioredis

    client = aioredis.Redis.from_url(REDIS)
    pubsub = client.pubsub(ignore_subscribe_messages=True)
    await pubsub.subscribe(topic)
    ready()
    delays: list[float] = []
    deadline = time.monotonic() + seconds + 10
    while len(delays) < count and time.monotonic() < deadline:
        message = await pubsub.get_message(timeout=1.0)
        if message is not None:
            delays.append(delay(message["data"]))
    await pubsub.aclose()
    await client.aclose()
    return delays


async def streams_pub(topic: str, messages: list[bytes], rate: float) -> None:
    import redis.asyncio as aioredis

    client = aioredis.Redis.from_url(REDIS)
    await paced(messages, rate, lambda m: client.xadd(topic, {"m": m}, maxlen=10000))
    await client.aclose()


async def streams_sub(topic: str, ready: Any, count: int, seconds: float) -> list[float]:
    import redis.asyncio as aioredis

    client = aioredis.Redis.from_url(REDIS)
    last = "$"
    ready()
    delays: list[float] = []
    deadline = time.monotonic() + seconds + 10
    while len(delays) < count and time.monotonic() < deadline:
        answer = await client.xread({topic: last}, block=1000, count=1000)
        for _, entries in answer:
            for entry_id, fields in entries:
                last = entry_id
                delays.append(delay(fields[b"m"]))
    await client.aclose()
    return delays


async def pg_pub(topic: str, messages: list[bytes], rate: float) -> None:
    import psycopg

    async with await psycopg.AsyncConnection.connect(POSTGRES, autocommit=True) as conn:

        async def notify(m: bytes) -> None:
            await conn.execute("SELECT pg_notify(%s, %s)", (topic, m.decode()))

        await paced(messages, rate, notify)


async def pg_sub(topic: str, ready: Any, count: int, seconds: float) -> list[float]:
    import psycopg

    delays: list[float] = []
    async with await psycopg.AsyncConnection.connect(POSTGRES, autocommit=True) as conn:
        await conn.execute(f'LISTEN "{topic}"')
        ready()
        gen = conn.notifies(timeout=seconds + 10, stop_after=count)
        async for note in gen:
            delays.append(delay(note.payload.encode()))
    return delays


async def nats_pub(topic: str, messages: list[bytes], rate: float) -> None:
    import nats

    nc = await nats.connect(NATS)
    js = nc.jetstream()
    await js.add_stream(name=topic, subjects=[topic], max_msgs=10000)
    await paced(messages, rate, lambda m: js.publish(topic, m))
    await nc.drain()


async def nats_sub(topic: str, ready: Any, count: int, seconds: float) -> list[float]:
    import nats

    nc = await nats.connect(NATS)
    js = nc.jetstream()
    delays: list[float] = []
    done = asyncio.Event()

    async def handler(msg: Any) -> None:
        delays.append(delay(msg.data))
        if len(delays) >= count:
            done.set()

    await js.add_stream(name=topic, subjects=[topic], max_msgs=10000)  # idempotent
    await js.subscribe(topic, cb=handler, manual_ack=False, ordered_consumer=True)
    ready()
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(done.wait(), seconds + 10)
    await nc.close()
    return delays


BUSES: dict[str, tuple[Any, Any, str]] = {
    "redis": (redis_pub, redis_sub, "redis-server"),
    "redis-streams": (streams_pub, streams_sub, "redis-server"),
    "postgres": (pg_pub, pg_sub, "postgres"),
    "nats": (nats_pub, nats_sub, "nats-server"),
}


def delay(data: bytes) -> float:
    sent = float(data[: data.index(b" ")])
    return 1000.0 * (time.monotonic() - sent)


async def paced(messages: list[bytes], rate: float, send: Any) -> None:
    start = time.monotonic()
    for i, body in enumerate(messages):
        wait = start + i / rate - time.monotonic()
        if wait > 0:
            await asyncio.sleep(wait)
        await send(f"{time.monotonic():.6f} ".encode() + body)


# -- the driver -----------------------------------------------------------------------------------


def run_bus(name: str, rate: float, seconds: float, subscribers: int) -> dict[str, Any]:
    topic = f"bench_{uuid.uuid4().hex[:8]}"
    count = int(rate * seconds)
    subs = [
        subprocess.Popen(
            [sys.executable, SCRIPT, "--role", "sub", "--bus", name, "--topic", topic,
             "--count", str(count), "--seconds", str(seconds)],
            stdout=subprocess.PIPE,
            text=True,
        )
        for _ in range(subscribers)
    ]  # fmt: skip
    for sub in subs:
        assert sub.stdout is not None
        line = sub.stdout.readline().strip()
        if line != "ready":
            for other in subs:
                other.kill()
            return {"bus": name, "skipped": line or "the subscriber stopped"}
    brokers = broker_pids(BUSES[name][2])
    before = {
        "sub": sum(cpu_seconds(s.pid) for s in subs),
        "broker": sum(cpu_seconds(p) for p in brokers),
    }
    wall = time.monotonic()
    pub = subprocess.Popen(
        [sys.executable, SCRIPT, "--role", "pub", "--bus", name, "--topic", topic,
         "--count", str(count), "--rate", str(rate)],
    )  # fmt: skip
    pub_cpu = 0.0
    while pub.poll() is None:
        pub_cpu = max(pub_cpu, cpu_seconds(pub.pid))
        time.sleep(0.05)
    delays: list[float] = []
    sub_cpu = 0.0
    for sub in subs:
        assert sub.stdout is not None
        sub_cpu += cpu_seconds(sub.pid)
        delays += json.loads(sub.stdout.readline())
        sub.wait()
    wall = time.monotonic() - wall
    broker_cpu = sum(cpu_seconds(p) for p in brokers) - before["broker"]
    delays.sort()
    out: dict[str, Any] = {
        "bus": name,
        "delivered": len(delays) / max(1, count * subscribers),
        "pub_cpu": 100 * pub_cpu / wall,
        "sub_cpu": 100 * (sub_cpu - before["sub"]) / wall,
        "broker_cpu": 100 * broker_cpu / wall,
    }
    if delays:
        out |= {
            "p50": delays[len(delays) // 2],
            "p99": delays[min(len(delays) - 1, int(0.99 * len(delays)))],
            "max": delays[-1],
        }
    return out


def role_main(args: argparse.Namespace) -> None:
    publish, subscribe, _ = BUSES[args.bus]
    if args.role == "pub":
        messages = [f'{{"k":{k},"pad":"{PAD}"}}'.encode() for k in range(args.count)]
        asyncio.run(publish(args.topic, messages, args.rate))
        return

    def ready() -> None:
        print("ready", flush=True)

    try:
        delays = asyncio.run(subscribe(args.topic, ready, args.count, args.seconds))
    except Exception as exc:  # the server or client is absent: say why
        print(f"skipped: {type(exc).__name__}: {exc}".replace("\n", " "), flush=True)
        return
    print(json.dumps(delays), flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1000.0, help="messages a second (1000)")
    parser.add_argument("--seconds", type=float, default=5.0, help="how long (5)")
    parser.add_argument("--subscribers", type=int, default=4, help="subscriber workers (4)")
    parser.add_argument("--buses", default=",".join(BUSES), help="comma-separated")
    parser.add_argument("--role", choices=["pub", "sub"], help=argparse.SUPPRESS)
    parser.add_argument("--bus", help=argparse.SUPPRESS)
    parser.add_argument("--topic", help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role:
        role_main(args)
        return 0
    print(
        f"{args.rate:g} messages/s of ~600 B for {args.seconds:g} s to {args.subscribers} "
        f"subscriber processes; {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}"
    )
    print("  bus              deliv%    p50 ms    p99 ms    max ms  pubCPU  subCPU  brokerCPU")
    for name in args.buses.split(","):
        row = run_bus(name, args.rate, args.seconds, args.subscribers)
        if "skipped" in row:
            print(f"  {name:<15} {row['skipped']}")
            continue
        print(
            f"  {name:<15} {100 * row['delivered']:6.2f}  {row.get('p50', float('nan')):8.2f}  "
            f"{row.get('p99', float('nan')):8.2f}  {row.get('max', float('nan')):8.2f}  "
            f"{row['pub_cpu']:6.0f}  {row['sub_cpu']:6.0f}  {row['broker_cpu']:9.0f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
