"""Load benchmark of the live stream: N watchers of one rig sampled at 10 Hz.

For each number of watchers, two servers are measured in turn with the same
clients:

* **thermolab**: ``thermolab serve`` in a child process (a SQLite database in a
  temporary folder, the realistic twin in real time). A teacher takes
  control and starts a run at ``dt = 0.1 s`` with LSM and WLSM, so every
  watcher gets 10 ``sample`` and 10 ``estimate`` messages a second.
* **peer**: a bare ``websockets`` broadcast server in a child process of its
  own (uvloop, no database, no identifiers, no per-client queues) that
  broadcasts a ``sample`` and an ``estimate`` message of the same shape and
  size every 0.1 s, one WebSocket frame per message. Like ours it does not
  negotiate per-message compression.

The watchers are real WebSocket connections on loopback, spread over
``--client-procs`` client processes (uvloop, the ``websockets`` sans-I/O
protocol behind a bare asyncio protocol: the library parses the frames, and a
frame is decoded only as far as needed to read the sample number ``k``), so
the clients' own cost stays small; their CPU is reported beside the
server's. One more watcher is *stalled*: it connects with a small receive
buffer and never reads after the handshake; at the end it reads what had
reached it, to tell whether the server cut it (4408) or kept it.

Delay of a sample at a watcher = arrival - (t0 + k dt), with t0 the run's
start as the earliest arrival of any sample shows it (min over watchers and k
of ``arrival - k dt``): the figures are the delay beyond the fastest delivery
seen, i.e. queueing in the server and clients (and the sampling loop's own
lateness), not the loopback's fixed cost. All processes use the system's
monotonic clock.

CPU is measured from ``/proc`` (Linux) between the first sample reaching the
first client process and the last watcher seeing the end of the run, as a
percentage of one core, for the server and for all client processes
together, beside the whole machine's busy time (100 % = both cores).

Usage::

    .venv/bin/python benchmarks/bench_live.py                    # 50, 200, 500 watchers, 20 s
    .venv/bin/python benchmarks/bench_live.py --watchers 500 --seconds 30 --client-procs 2
    .venv/bin/python benchmarks/bench_live.py --watchers 500 --compete 6   # a busy machine
    .venv/bin/python benchmarks/bench_live.py --replay 4 --seconds 8   # a student replaying

``--replay N`` measures instead another user's request latency and reading
delays without, then with, a student replaying a 200 000-sample run on N
sockets (see "the replay scenario" below).
"""

from __future__ import annotations

import argparse
import array
import asyncio
import contextlib
import json
import math
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import httpx
from websockets.client import ClientProtocol
from websockets.extensions.permessage_deflate import ClientPerMessageDeflateFactory
from websockets.frames import Opcode
from websockets.http11 import Response
from websockets.uri import parse_uri

PYTHON = sys.executable
SCRIPT = str(Path(__file__).resolve())
DT = 0.1
TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def wait_for(url: str, seconds: float = 60.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with contextlib.suppress(httpx.HTTPError):
            httpx.get(url, timeout=1.0)
            return
        time.sleep(0.1)
    raise SystemExit(f"the server at {url} did not start")


def new_loop() -> asyncio.AbstractEventLoop:
    try:
        import uvloop
    except ImportError:  # pragma: no cover - uvicorn[standard] brings it
        return asyncio.new_event_loop()
    return uvloop.new_event_loop()


# -- the watchers (client processes) ------------------------------------------------------------


class Watcher(asyncio.Protocol):
    """One WebSocket client: notes (k, arrival) of each run sample it receives.

    ``websockets``' sans-I/O ``ClientProtocol`` does the handshake and parses
    frames; the frame's text is decoded only when it may hold a sample.
    """

    def __init__(
        self, url: str, cookie: str | None, stalled: bool = False, ping: float = 0.0
    ) -> None:
        self.url = url
        self.ping = ping
        self.cookie = cookie
        self.stalled = stalled
        self.ws = ClientProtocol(parse_uri(url), extensions=[ClientPerMessageDeflateFactory()])
        self.transport: asyncio.Transport | None = None
        self.opened: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.ended: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.first: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        # thermolab's watcher is attached to the stream once its hello came (the peer has none).
        self.hello: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.hello.add_done_callback(lambda f: f.cancelled() or f.exception())  # read: no warning
        self.ks = array.array("i")
        self.arrivals = array.array("d")
        self.counts: Counter[str] = Counter()
        self.frames = 0
        self.close_code: int | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.Transport, transport)  # uvloop's is not a subclass
        request = self.ws.connect()
        if self.cookie:
            request.headers["Cookie"] = self.cookie
        self.ws.send_request(request)
        self._flush()

    def data_received(self, data: bytes) -> None:
        now = time.monotonic()
        self.ws.receive_data(data)
        for event in self.ws.events_received():
            if isinstance(event, Response):
                if self.ws.handshake_exc is not None:
                    self._done(self.opened, self.ws.handshake_exc)
                else:
                    self._done(self.opened)
                    if self.stalled and self.transport is not None:
                        self.transport.pause_reading()
                    elif self.ping > 0:  # as the browser does: a ping every few seconds
                        loop = asyncio.get_running_loop()
                        loop.call_later(self.ping * (0.1 + 0.9 * random.random()), self._ping)
            elif event.opcode is Opcode.TEXT:
                self.frames += 1
                self._text(event.data, now)
            elif event.opcode is Opcode.CLOSE:
                self.close_code = self.ws.close_rcvd.code if self.ws.close_rcvd else None
                self._done(self.hello, ConnectionError(f"closed with {self.close_code}"))
                self._done(self.ended)
        self._flush()

    def connection_lost(self, exc: Exception | None) -> None:
        self._done(self.opened, exc or ConnectionError("closed before the handshake"))
        self._done(self.hello, exc or ConnectionError("closed before the hello"))
        self._done(self.ended)

    def _text(self, data: bytes, now: float) -> None:
        if data.startswith(b'{"type":"estimate"'):
            self.counts["estimate"] += 1  # the bulk of the rest: not decoded
            return
        decoded = json.loads(data)
        for message in decoded if isinstance(decoded, list) else (decoded,):
            kind = message.get("type")
            if kind == "hello":
                self._done(self.hello)
            self.counts[kind] += 1
            if (kind == "sample" and message.get("run") is not None) or kind == "tick":
                self.ks.append(message["k"])
                self.arrivals.append(now)
                self._done(self.first)
            elif (kind == "run" and message.get("event") == "ended") or kind == "end":
                self._done(self.ended)

    def _ping(self) -> None:
        if self.transport is None or self.transport.is_closing() or self.ended.done():
            return
        self.ws.send_text(b'{"type":"ping"}')
        self._flush()
        asyncio.get_running_loop().call_later(self.ping, self._ping)

    def _flush(self) -> None:
        data = self.ws.data_to_send()
        if data and self.transport is not None and not self.transport.is_closing():
            self.transport.write(b"".join(data))

    @staticmethod
    def _done(future: asyncio.Future[None], exc: BaseException | None = None) -> None:
        if not future.done():
            if exc is None:
                future.set_result(None)
            else:
                future.set_exception(exc)


async def open_watcher(
    url: str, cookie: str | None, stalled: bool = False, ping: float = 0.0
) -> Watcher:
    for attempt in range(3):  # a loaded server may refuse a connection now and then
        try:
            return await _open_watcher(url, cookie, stalled, ping)
        except ConnectionError as exc:
            print(f"watcher connection failed ({exc}); again", file=sys.stderr, flush=True)
            if attempt == 2:
                raise
            await asyncio.sleep(0.5)
    raise AssertionError("unreachable")


async def _open_watcher(url: str, cookie: str | None, stalled: bool, ping: float) -> Watcher:
    loop = asyncio.get_running_loop()
    uri = parse_uri(url)
    sock = socket.socket()
    sock.setblocking(False)
    if stalled:  # a small window: the server's writes back up within seconds
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    await loop.sock_connect(sock, (uri.host, uri.port))
    _, watcher = await loop.create_connection(
        lambda: Watcher(url, cookie, stalled, ping), sock=sock
    )
    await watcher.opened
    if cookie and not stalled:
        await watcher.hello
    return watcher


async def client_main(
    url: str, cookie: str | None, count: int, stall: bool, ping: float = 0.0
) -> None:
    """A client process: ``count`` watchers (and maybe the stalled one); talks on stdio."""
    watchers: list[Watcher] = []
    for i in range(0, count, 50):  # in waves, as a class arrives
        watchers += await asyncio.gather(
            *(open_watcher(url, cookie, ping=ping) for _ in range(min(50, count - i)))
        )
    stalled = await open_watcher(url, cookie, stalled=True) if stall else None
    print("ready", flush=True)
    if stall:  # the first process says when the first sample came: CPU is measured from there
        await asyncio.wait([w.first for w in watchers], return_when=asyncio.FIRST_COMPLETED)
        print("first", flush=True)
    _, pending = await asyncio.wait([w.ended for w in watchers], timeout=120)
    print("done", flush=True)
    stall_report = None
    if stalled is not None and stalled.transport is not None:
        seen_before = stalled.frames
        stalled.transport.resume_reading()  # read what reached it: was it cut?
        await asyncio.sleep(1.0)
        stall_report = {
            "close_code": stalled.close_code,
            "frames_read_at_end": stalled.frames - seen_before,
            "samples": len(stalled.ks),
        }
    result = {
        "watchers": [
            {"k": w.ks.tolist(), "t": w.arrivals.tolist(), "frames": w.frames} for w in watchers
        ],
        "counts": dict(watchers[0].counts) if watchers else {},
        "unfinished": len(pending),
        "closed": dict(Counter(str(w.close_code) for w in watchers if w.close_code is not None)),
        "stalled": stall_report,
    }
    print(json.dumps(result), flush=True)
    for w in [*watchers, *([stalled] if stalled else [])]:
        if w.transport is not None:
            w.transport.abort()


# -- the peer server -----------------------------------------------------------------------------


def peer_messages(k: int, seq: int) -> tuple[str, str]:
    """A sample and an estimate of the same shape and size as thermolab's."""
    y = 2.5 + 0.7 * (1 - 0.999**k) + 1e-4 * ((k * 7919) % 13)
    sample = {"type": "tick", "run": 1, "k": k, "t": round(k * DT, 10), "u": 6.0, "y": y}
    estimate = {
        "type": "estimate",
        "run": 1,
        "method": "wlsm",
        "k": k,
        "K": 0.14009012345678 + 1e-9 * k,
        "tau": 250.12623312345 - 1e-7 * k,
        "W": [0.9996001120312345, 5.599217128412345e-05],
        "valid": True,
        "final": False,
        "reason": None,
        "seq": seq + 1,
    }
    sample["seq"] = seq
    return (
        json.dumps(sample, separators=(",", ":")),
        json.dumps(estimate, separators=(",", ":")),
    )


async def peer_main(port: int, samples: int) -> None:
    """The bare broadcast server: starts sending on ``go`` from stdin."""
    import websockets
    from websockets.asyncio.server import ServerConnection, broadcast, serve

    connected: set[ServerConnection] = set()

    async def handler(ws: ServerConnection) -> None:
        connected.add(ws)
        try:
            await ws.wait_closed()
        finally:
            connected.discard(ws)

    loop = asyncio.get_running_loop()
    async with serve(handler, "127.0.0.1", port, compression=None, max_queue=16):
        print("listening", flush=True)
        await loop.run_in_executor(None, sys.stdin.readline)  # "go"
        start = time.monotonic()
        seq = 10**15
        for k in range(samples):
            await asyncio.sleep(max(0.0, start + k * DT - time.monotonic()))
            sample, estimate = peer_messages(k, seq)
            seq += 2
            broadcast(connected, sample)
            broadcast(connected, estimate)
        broadcast(connected, json.dumps({"type": "end"}))
        await loop.run_in_executor(None, sys.stdin.readline)  # "stop"
    del websockets


# -- the replay scenario --------------------------------------------------------------------------
#
# One student keeps every live socket she may open replaying a 200 000-sample run from its
# start (since=0), reconnecting as soon as each replay ends; another user's HTTP requests
# and live readings are timed without her, then with her, against the same server.

REPLAY_STORED = 200_000
READING_DT = 0.1


def replay_server_main(port: int, data_dir: str) -> None:
    """The lab as ``thermolab serve`` runs it, ``twin``'s run held after its first sample."""
    import threading
    from datetime import UTC, datetime

    from thermolab.cli.http_server import run_server
    from thermolab.lab.config import LabConfig, RigConfig
    from thermolab.lab.http.app import create_app
    from thermolab.lab.service import Lab
    from thermolab.rigs import Rig, TwinRig, VirtualClock

    class Held:
        """A twin's clock that stops after time 0: the run stays running, sampling nothing."""

        def now(self) -> float:
            return 0.0

        def sleep_until(self, t: float) -> None:
            if t > 0:
                threading.Event().wait()

    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=Held() if rig.id == "twin" else VirtualClock())

    rigs = (RigConfig("twin", "Twin", "sim"), RigConfig("other", "Other", "sim"))
    lab = Lab(LabConfig(data_dir=Path(data_dir), rigs=rigs), opener=opener)
    app = create_app(lab.config, lab=lab, close_lab=True)
    lab.db.upgrade()  # the accounts first (the app's start-up finds the schema there)
    for name, role in (("mallory", "student"), ("olga", "student")):
        lab.users.add(name, "bench-password-0123", role)

    def readings() -> None:  # the sweep's idle readings of a powered rig, at 10 Hz
        while True:
            time.sleep(READING_DT)
            app.state.live.reading("other", 0.0, 1.0, datetime.now(UTC))

    threading.Thread(target=readings, daemon=True).start()
    run_server(app, "127.0.0.1", port)


def replayer_main(url: str, cookie: str, sockets: int, seconds: float) -> None:
    """Mallory: ``sockets`` sockets replaying from ``since=0`` again and again."""
    import threading

    from websockets.sync.client import connect

    stop = time.monotonic() + seconds
    counts: Counter[str] = Counter()
    lock = threading.Lock()

    def one_socket() -> None:
        while time.monotonic() < stop:
            try:
                with connect(url, additional_headers={"Cookie": cookie}, max_size=None) as ws:
                    ws.recv(timeout=60)  # hello
                    wait = 60.0  # for the replay to begin (it may wait its turn)
                    while time.monotonic() < stop:
                        try:
                            frame = json.loads(ws.recv(timeout=wait))
                        except TimeoutError:
                            break  # over: ask again
                        wait = 0.5
                        for message in frame if isinstance(frame, list) else [frame]:
                            if message.get("type") == "samples":
                                with lock:
                                    counts["samples"] += len(message["items"])
                    with lock:
                        counts["replays"] += 1
            except Exception:
                with lock:
                    counts["refused"] += 1
                time.sleep(0.1)

    threads = [threading.Thread(target=one_socket) for _ in range(sockets)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    print(json.dumps(dict(counts)), flush=True)


def time_others(base: str, cookie: str, seconds: float) -> tuple[list[float], list[float]]:
    """Olga's request latencies and reading delays (ms) over ``seconds``."""
    import threading
    from datetime import UTC, datetime

    from websockets.sync.client import connect

    requests: list[float] = []
    readings: list[float] = []
    stop = time.monotonic() + seconds

    def watch() -> None:
        url = base.replace("http", "ws", 1) + "/api/rigs/other/live"
        with connect(url, additional_headers={"Cookie": cookie}, max_size=None) as ws:
            while time.monotonic() < stop:
                with contextlib.suppress(TimeoutError):
                    frame = json.loads(ws.recv(timeout=0.5))
                    now = datetime.now(UTC).timestamp()
                    for message in frame if isinstance(frame, list) else [frame]:
                        if message.get("type") == "sample":
                            readings.append(1000 * (now - message["t"]))

    watcher = threading.Thread(target=watch)
    watcher.start()
    with httpx.Client(base_url=base, headers={"Cookie": cookie}, timeout=60) as http:
        while time.monotonic() < stop:
            start = time.perf_counter()
            http.get("/api/rigs/other").raise_for_status()
            requests.append(1000 * (time.perf_counter() - start))
            time.sleep(max(0.0, 0.05 - (time.perf_counter() - start)))
    watcher.join()
    return requests, readings


def bench_replay(seconds: float, sockets: int) -> None:
    """Others' latency without, then with, a student replaying on ``sockets`` sockets."""
    import sqlite3

    port = free_port()
    base = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory() as tmp:
        server = subprocess.Popen(
            [PYTHON, SCRIPT, "--role", "replay-server", "--port", str(port), "--data-dir", tmp],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        replayer = None
        try:
            wait_for(base + "/openapi.json")
            cookies = {}
            for name in ("mallory", "olga"):
                login = httpx.post(
                    base + "/api/session",
                    json={"username": name, "password": "bench-password-0123"},
                )
                login.raise_for_status()
                cookies[name] = f"thermolab_session={login.cookies['thermolab_session']}"
            mallory = {"Cookie": cookies["mallory"]}
            httpx.post(base + "/api/rigs/twin/control", headers=mallory).raise_for_status()
            run = httpx.post(
                base + "/api/rigs/twin/runs",
                headers=mallory,
                json={"dt": 0.01, "samples": REPLAY_STORED, "methods": ["lsm"]},
            )
            run.raise_for_status()
            run_id = run.json()["id"]
            time.sleep(1.5)  # the first sample reaches the store
            with contextlib.closing(sqlite3.connect(Path(tmp, "thermolab.sqlite3"))) as db:
                db.executemany(
                    "INSERT INTO samples (run_id, k, t, u, y) VALUES (?, ?, ?, 5.0, ?)",
                    ((run_id, k, 0.01 * k, 0.7 * (1 - 0.9999**k)) for k in range(1, REPLAY_STORED)),
                )
                db.commit()
            rows = {}
            rows["alone"] = time_others(base, cookies["olga"], seconds)
            replayer = subprocess.Popen(
                [
                    PYTHON,
                    SCRIPT,
                    "--role",
                    "replayer",
                    "--url",
                    base.replace("http", "ws", 1) + "/api/rigs/twin/live?since=0",
                    "--cookie",
                    cookies["mallory"],
                    "--count",
                    str(sockets),
                    "--seconds",
                    str(seconds + 2),
                ],
                stdout=subprocess.PIPE,
                text=True,
            )
            time.sleep(1.0)  # the replays under way
            rows[f"replaying x{sockets}"] = time_others(base, cookies["olga"], seconds)
            replayed = json.loads(replayer.communicate(timeout=120)[0])
        finally:
            if replayer is not None and replayer.poll() is None:
                replayer.kill()
                replayer.communicate()
            server.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                server.wait(timeout=20)
    print(
        f"another user's latency (ms) while a student replays a {REPLAY_STORED}-sample run "
        f"on {sockets} sockets; {seconds:g} s each; load {os.getloadavg()[0]:.1f}"
    )
    print("                      requests p50   p95   max | readings p50   p95   max")
    for name, (requests, readings) in rows.items():
        q = [statistics_of(requests), statistics_of(readings)]
        print(
            f"  {name:>18}  {q[0][0]:12.1f} {q[0][1]:5.1f} {q[0][2]:5.0f} |"
            f" {q[1][0]:12.1f} {q[1][1]:5.1f} {q[1][2]:5.0f}   ({len(requests)} requests)"
        )
    print(f"  the student's replays: {replayed}")


def statistics_of(values: list[float]) -> tuple[float, float, float]:
    """p50, p95 and max of ``values`` (NaN when empty)."""
    if not values:
        return (math.nan, math.nan, math.nan)
    ordered = sorted(values)
    return (
        ordered[len(ordered) // 2],
        ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))],
        ordered[-1],
    )


# -- the orchestration ---------------------------------------------------------------------------


def cpu_seconds(pid: int) -> float:
    """User + system CPU of a process (all its threads) so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def machine_busy() -> tuple[float, float]:
    """(busy, total) CPU seconds of the whole machine so far, all cores."""
    values = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = values[3] + values[4]
    total = sum(values[:8])
    return (total - idle) / TICKS, total / TICKS


@dataclass
class CpuWindow:
    pids: dict[str, list[int]]
    start: dict[str, float] | None = None
    machine: tuple[float, float] | None = None
    wall: float = 0.0

    last: dict[int, float] = field(default_factory=dict)

    def _read(self) -> dict[str, float]:
        # A client process that has already reported and exited counts with its last reading.
        for pids in self.pids.values():
            for pid in pids:
                with contextlib.suppress(FileNotFoundError, ProcessLookupError):
                    self.last[pid] = cpu_seconds(pid)
        return {name: sum(self.last.get(p, 0.0) for p in pids) for name, pids in self.pids.items()}

    def begin(self) -> None:
        self.start, self.machine, self.wall = self._read(), machine_busy(), time.monotonic()

    def end(self) -> dict[str, float]:
        assert self.start is not None
        assert self.machine is not None
        now, busy, wall = self._read(), machine_busy(), time.monotonic() - self.wall
        out = {f"{name}_cpu": 100 * (now[name] - self.start[name]) / wall for name in now}
        out["machine_busy"] = (
            100 * (busy[0] - self.machine[0]) / max(1e-9, busy[1] - self.machine[1])
        )
        return out


async def start_clients(
    url: str, cookie: str | None, watchers: int, procs: int, ping: float = 0.0
) -> list[asyncio.subprocess.Process]:
    shares = [watchers // procs + (1 if i < watchers % procs else 0) for i in range(procs)]
    clients = []
    for i, share in enumerate(shares):
        command = [SCRIPT, "--role", "clients", "--url", url, "--count", str(share)]
        if cookie:
            command += ["--cookie", cookie]
        if ping > 0:
            command += ["--ping", str(ping)]
        if i == 0:
            command.append("--stall")
        clients.append(
            await asyncio.create_subprocess_exec(
                PYTHON, *command, stdout=asyncio.subprocess.PIPE, limit=2**28
            )
        )
    for client in clients:
        await expect(client, "ready", 120)
    return clients


async def expect(process: asyncio.subprocess.Process, word: str, timeout: float) -> None:
    assert process.stdout is not None
    line = await asyncio.wait_for(process.stdout.readline(), timeout)
    if line.decode().strip() != word:
        raise SystemExit(f"a client process said {line!r}, expected {word!r}")


async def measure(
    clients: list[asyncio.subprocess.Process], cpu: CpuWindow, seconds: float
) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """From the first sample to the end of the run: CPU, then every client's result."""
    await expect(clients[0], "first", seconds + 60)
    cpu.begin()
    for client in clients:
        await expect(client, "done", seconds + 180)
    figures = cpu.end()
    results = []
    for client in clients:
        assert client.stdout is not None
        results.append(json.loads(await client.stdout.readline()))
        await client.wait()
    return results, figures


def summarise(
    name: str, results: list[dict[str, Any]], cpu: dict[str, float], samples: int
) -> dict[str, Any]:
    flat_k: list[int] = []
    flat_t: list[float] = []
    frames = 0
    for result in results:
        for watcher in result["watchers"]:
            flat_k += watcher["k"]
            flat_t += watcher["t"]
            frames += watcher["frames"]
    watchers = sum(len(r["watchers"]) for r in results)
    out: dict[str, Any] = {"name": name, "watchers": watchers, **cpu}
    out["counts"] = results[0]["counts"]
    out["stalled"] = results[0]["stalled"]
    closed: Counter[str] = Counter()
    for result in results:
        closed.update(result.get("closed", {}))
    out["closed"] = dict(closed)
    out["unfinished"] = sum(r["unfinished"] for r in results)
    out["frames_per_watcher"] = frames / max(1, watchers)
    out["delivered"] = len(flat_k) / (watchers * samples)
    # Samples the run produced (as far as any watcher saw): below ``samples`` when the run
    # itself ended early (its sampling fell behind on a starved machine), not the stream.
    out["produced"] = len(set(flat_k))
    # Watchers short of samples: those missing the run's start, its end, or some between.
    short = Counter()
    for result in results:
        for watcher in result["watchers"]:
            ks = watcher["k"]
            if len(ks) == samples:
                continue
            if not ks or ks[0] > 0:
                short["start"] += 1
            if not ks or ks[-1] < samples - 1:
                short["end"] += 1
            if ks and len(ks) < ks[-1] - ks[0] + 1:
                short["between"] += 1
    out["short"] = dict(short)
    if flat_k:
        t0 = min(t - k * DT for k, t in zip(flat_k, flat_t, strict=True))
        values = sorted((t - (t0 + k * DT)) * 1000.0 for k, t in zip(flat_k, flat_t, strict=True))
        out["p50"] = values[len(values) // 2]
        out["p99"] = values[min(len(values) - 1, int(0.99 * len(values)))]
        out["max"] = values[-1]
    return out


# Every watcher uses the teacher's one login (one socket per tab would be 4 at most).
LAB_TOML = """
[access]
login_attempts_per_address = 1000
live_sockets_per_login = 10000
live_sockets_per_rig = 10000

[rig_defaults]
control_time_limit = 3600
idle_limit = 0

[[rigs]]
id = "twin"
title = "Twin"
spec = "sim:paper-practical"
"""


@dataclass
class RunningLab:
    """``thermolab serve`` in a child process, a teacher holding the twin's controls."""

    server: subprocess.Popen[bytes]
    http: httpx.AsyncClient
    cookie: str
    url: str  # the twin's live stream
    student_cookie: str  # a student's login, who only watches
    beats: list[float] = field(default_factory=list)  # the controller's heartbeats, ms

    async def start_run(self, samples: int) -> None:
        """START a run of ``samples`` at ``DT`` with LSM and WLSM (a square wave of 4 to 6)."""
        started = await self.http.post(
            "/api/rigs/twin/runs",
            headers={"Cookie": self.cookie},
            json={
                "dt": DT,
                "samples": samples,
                "signal": "square:4:6:0.1",
                "methods": ["lsm", "wlsm"],
            },
        )
        started.raise_for_status()


@contextlib.asynccontextmanager
async def running_lab(profile: str | None = None) -> Any:
    """A lab on the twin (SQLite in a temporary folder) whose teacher holds the controls."""
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp, "lab.toml")
        config.write_text(textwrap.dedent(LAB_TOML))
        env = dict(os.environ, THERMOLAB_DATA_DIR=tmp)
        thermolab = [PYTHON, "-m", "thermolab"]
        for name, role in (("tina", "teacher"), ("sam", "student")):
            subprocess.run(
                [
                    *thermolab,
                    "user",
                    "add",
                    name,
                    "--role",
                    role,
                    "--password-stdin",
                    "--config",
                    str(config),
                ],
                input="bench-password\n",
                text=True,
                env=env,
                check=True,
                capture_output=True,
            )
        serve = [*thermolab, "serve", "--port", str(port), "--config", str(config)]
        serve += ["--max-connections", "20000"]
        if profile:  # py-spy samples the server (PyPI: py-spy), a flame graph per run
            serve = [
                "py-spy",
                "record",
                "--rate",
                "50",
                "--format",
                "raw",
                "-o",
                profile,
                "--",
                *serve,
            ]
        server = subprocess.Popen(
            serve,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            base = f"http://127.0.0.1:{port}"
            wait_for(base + "/openapi.json")
            async with httpx.AsyncClient(base_url=base, timeout=60) as http:
                login = await http.post(
                    "/api/session", json={"username": "tina", "password": "bench-password"}
                )
                login.raise_for_status()
                cookie = f"thermolab_session={login.cookies['thermolab_session']}"
                headers = {"Cookie": cookie}
                (await http.post("/api/rigs/twin/control", headers=headers)).raise_for_status()
                http.cookies.clear()  # a login from this client would end the teacher's
                student = await http.post(
                    "/api/session", json={"username": "sam", "password": "bench-password"}
                )
                student.raise_for_status()
                http.cookies.clear()  # each request names its login
                lab = RunningLab(
                    server,
                    http,
                    cookie,
                    f"ws://127.0.0.1:{port}/api/rigs/twin/live",
                    f"thermolab_session={student.cookies['thermolab_session']}",
                )

                async def keep_control() -> None:  # the controller's page keeps its turn
                    while True:
                        await asyncio.sleep(5.0)
                        sent = time.monotonic()
                        await http.post("/api/rigs/twin/heartbeat", headers=headers)
                        lab.beats.append(1000.0 * (time.monotonic() - sent))

                # From the start: connecting hundreds of watchers may outlast the 15 s a
                # silent controller keeps the turn (and a run ends with its turn).
                heartbeat = asyncio.create_task(keep_control())
                try:
                    yield lab
                finally:
                    heartbeat.cancel()
                    with contextlib.suppress(asyncio.CancelledError):
                        await heartbeat
        finally:
            server.send_signal(signal.SIGINT)  # py-spy writes its graph on the server's exit
            with contextlib.suppress(subprocess.TimeoutExpired):
                server.wait(timeout=30)
            if server.poll() is None:
                server.kill()


async def bench_thermolab(
    watchers: int, seconds: float, procs: int, ping: float = 0.0, profile: str | None = None
) -> dict[str, Any]:
    samples = round(seconds / DT)
    clients: list[asyncio.subprocess.Process] = []
    try:
        async with running_lab(f"{profile}-{watchers}.txt" if profile else None) as lab:
            clients = await start_clients(lab.url, lab.cookie, watchers, procs, ping)
            lab.beats.clear()  # the heartbeats while the run goes on
            cpu = CpuWindow({"server": [lab.server.pid], "clients": [c.pid for c in clients]})
            await lab.start_run(samples)
            results, figures = await measure(clients, cpu, seconds)
            beats = list(lab.beats)
    finally:
        kill(clients)
    row = summarise("thermolab", results, figures, samples)
    row["heartbeat_max"] = max(beats, default=math.nan)
    return row


@contextlib.asynccontextmanager
async def running_peer(samples: int) -> Any:
    """The bare broadcast server in a child process, listening: yields it and its URL.

    Its ``samples`` start on :func:`go`; it stops at the block's end.
    """
    port = free_port()
    peer = await asyncio.create_subprocess_exec(
        PYTHON,
        SCRIPT,
        *("--role", "peer", "--port", str(port), "--samples", str(samples)),
        stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE,
    )
    assert peer.stdin is not None
    try:
        await expect(peer, "listening", 60)
        yield peer, f"ws://127.0.0.1:{port}/"
        peer.stdin.write(b"stop\n")
        await peer.stdin.drain()
        await asyncio.wait_for(peer.wait(), 30)
    finally:
        with contextlib.suppress(ProcessLookupError):
            peer.kill()


def kill(processes: list[asyncio.subprocess.Process]) -> None:
    """Kill the client processes still running."""
    for process in processes:
        with contextlib.suppress(ProcessLookupError):
            process.kill()


async def go(peer: asyncio.subprocess.Process) -> None:
    """Start the peer's samples."""
    assert peer.stdin is not None
    peer.stdin.write(b"go\n")
    await peer.stdin.drain()


async def bench_peer(watchers: int, seconds: float, procs: int) -> dict[str, Any]:
    samples = round(seconds / DT)
    clients: list[asyncio.subprocess.Process] = []
    try:
        async with running_peer(samples) as (peer, url):
            clients = await start_clients(url, None, watchers, procs)
            cpu = CpuWindow({"server": [peer.pid], "clients": [c.pid for c in clients]})
            await go(peer)
            results, figures = await measure(clients, cpu, seconds)
    finally:
        kill(clients)
    return summarise("peer", results, figures, samples)


@contextlib.contextmanager
def competing(count: int) -> Iterator[None]:
    """``count`` processes spinning on the CPU while the block runs."""
    spinners = [subprocess.Popen([PYTHON, "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()


def stalled_text(report: dict[str, Any] | None) -> str:
    if report is None:
        return "n/a"
    if report["close_code"] is not None:
        return f"cut with {report['close_code']} after {report['samples']} samples"
    return f"kept (it had {report['samples']} samples when it read again)"


def print_row(row: dict[str, Any]) -> None:
    if "p99" not in row:
        print(f"  {row['name']:>9}  no samples received")
        return
    print(
        f"  {row['name']:>9}  {row['p50']:7.1f}  {row['p99']:7.1f}  {row['max']:7.1f}  "
        f"{100 * row['delivered']:6.2f}  {row['frames_per_watcher'] / row['expected_s']:6.1f}  "
        f"{row['server_cpu']:5.0f}  {row['clients_cpu']:5.0f}  {row['machine_busy']:5.0f}   "
        f"{stalled_text(row['stalled'])}"
        + (f"; heartbeat max {row['heartbeat_max']:.0f} ms" if "heartbeat_max" in row else "")
        + (f"; closed {row['closed']}" if row.get("closed") else "")
        + (f"; watchers short of samples {row['short']}" if row.get("short") else "")
        + (
            f"; the run produced {row['produced']} samples of {round(row['expected_s'] / DT)}"
            if row.get("produced", math.inf) < round(row["expected_s"] / DT)
            else ""
        )
        + (f"; {row['unfinished']} unfinished" if row.get("unfinished") else "")
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--watchers", default="50,200,500", help="comma-separated (50,200,500)")
    parser.add_argument("--seconds", type=float, default=20.0, help="length of each run (20)")
    parser.add_argument("--client-procs", type=int, default=2, help="client processes (2)")
    parser.add_argument("--only", choices=["thermolab", "peer"], help="measure one server")
    parser.add_argument(
        "--ping",
        type=float,
        default=0.0,
        metavar="S",
        help="each watcher pings every S seconds, as the browser does every 5 (0: never)",
    )
    parser.add_argument(
        "--profile",
        metavar="PREFIX",
        help="sample thermolab's server with py-spy into PREFIX-<watchers>.txt (collapsed stacks)",
    )
    parser.add_argument(
        "--compete",
        type=int,
        default=0,
        metavar="N",
        help="run N busy-loop processes meanwhile, competing for the cores (0)",
    )
    parser.add_argument(
        "--replay",
        type=int,
        default=0,
        metavar="SOCKETS",
        help="instead: others' latency while a student replays a long run on SOCKETS sockets",
    )
    parser.add_argument(
        "--role",
        choices=["clients", "peer", "replay-server", "replayer"],
        help=argparse.SUPPRESS,
    )
    parser.add_argument("--url", help=argparse.SUPPRESS)
    parser.add_argument("--cookie", help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--stall", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--port", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--data-dir", help=argparse.SUPPRESS)
    parser.add_argument("--samples", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "clients":
        new_loop().run_until_complete(
            client_main(args.url, args.cookie, args.count, args.stall, args.ping)
        )
        return 0
    if args.role == "peer":
        new_loop().run_until_complete(peer_main(args.port, args.samples))
        return 0
    if args.role == "replay-server":
        replay_server_main(args.port, args.data_dir)
        return 0
    if args.role == "replayer":
        replayer_main(args.url, args.cookie, args.count, args.seconds)
        return 0
    if args.replay:
        bench_replay(args.seconds, args.replay)
        return 0

    counts = [int(n) for n in args.watchers.split(",")]
    print(
        f"one rig at {1 / DT:g} samples/s (a sample and an estimate message each), "
        f"{args.seconds:g} s per run, watchers in {args.client_procs} client processes, "
        f"plus one stalled watcher; {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}"
        + (f", {args.compete} busy-loop processes competing" if args.compete else "")
    )
    print(
        "  delays in ms beyond the fastest delivery seen; CPU in % of one core "
        "(machine: % of all cores)"
    )
    print(
        "     server      p50      p99      max  deliv%  frm/s  srvCPU cliCPU  mach%   "
        "stalled watcher"
    )
    ok = True
    for watchers in counts:
        print(f"  -- {watchers} watchers")
        for name, bench in (("thermolab", bench_thermolab), ("peer", bench_peer)):
            if args.only is not None and args.only != name:
                continue
            with competing(args.compete):
                if name == "thermolab":
                    row = asyncio.run(
                        bench_thermolab(
                            watchers, args.seconds, args.client_procs, args.ping, args.profile
                        )
                    )
                else:
                    row = asyncio.run(bench(watchers, args.seconds, args.client_procs))
            row["expected_s"] = args.seconds
            print_row(row)
            if name == "thermolab" and watchers == 500:
                ok = row.get("p99", 1e9) < 100.0 and row["delivered"] > 0.999
    if 500 in counts and args.only != "peer":
        verdict = "met" if ok else "NOT met"
        print(f"target (500 watchers: p99 < 100 ms, every sample delivered): {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
