"""Real processes for the agent tests and the benchmark: a TLS lab, rig hosts, a test CA.

The CA and the lab's certificate are made here with ``cryptography``; the lab
is ``thermolab serve`` with ``--ssl-certfile``; each agent is ``thermolab
agent`` dialling ``wss://127.0.0.1:PORT``. Nothing is injected: the test
talks HTTP(S) to the lab and reads the lab's database only through the API.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import signal
import socket
import ssl
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

PASSWORD = "a long enough password"
#: A lab whose one rig, ``box``, is a TCLab twin on a rig host; nobody's turn or power
#: lapses while a test pauses or cuts the link.
ONE_REMOTE_BOX = """
[rig_defaults]
power_off_grace = 600
idle_limit = 600

[[rigs]]
id = "box"
spec = "sim:tclab"
agent = true
"""


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def make_ca(folder: Path, extra_ip: str | None = None) -> tuple[Path, Path, Path]:
    """A test CA and a certificate for 127.0.0.1 (and ``extra_ip``) signed by it."""
    now = dt.datetime.now(dt.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "ThermoLab test CA")])
    ca = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .sign(ca_key, hashes.SHA256())
    )
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "127.0.0.1")]))
        .issuer_name(ca_name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(
            x509.SubjectAlternativeName(
                [
                    x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
                    *([x509.IPAddress(ipaddress.ip_address(extra_ip))] if extra_ip else []),
                    x509.DNSName("localhost"),
                ]
            ),
            critical=False,
        )
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
            critical=False,
        )
        .add_extension(
            x509.ExtendedKeyUsage([x509.oid.ExtendedKeyUsageOID.SERVER_AUTH]), critical=False
        )
        .sign(ca_key, hashes.SHA256())
    )
    paths = (folder / "ca.pem", folder / "cert.pem", folder / "key.pem")
    paths[0].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    paths[1].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    paths[2].write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return paths


def thermolab(data_dir: Path, *args: str, stdin: str | None = None) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "thermolab", "--data-dir", str(data_dir), *args],
        input=stdin,
        text=True,
        capture_output=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


@dataclass
class Fleet:
    """A TLS lab with remote rigs, and the processes started for it."""

    data_dir: Path
    config: Path
    ca: Path
    url: str = ""
    agent_url: str = ""
    lab: subprocess.Popen[bytes] | None = None
    others: list[subprocess.Popen[bytes]] = field(default_factory=list)
    logs: list[object] = field(default_factory=list)

    def start_lab(
        self,
        cert: Path,
        key: Path,
        *,
        grace: float,
        agent_host: str | None = None,
        port: int | None = None,
    ) -> None:
        """Serve on 127.0.0.1 (and every address when agents dial ``agent_host``).

        ``port``: the one to serve on (a restart keeps the agents' address); default a free one.
        """
        port = port or free_port()
        host = "127.0.0.1" if agent_host is None else "0.0.0.0"
        self.url = f"https://127.0.0.1:{port}"
        self.agent_url = f"wss://{agent_host or '127.0.0.1'}:{port}"
        log = (self.data_dir / "lab.log").open("ab")
        self.logs.append(log)
        self.lab = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "thermolab",
                "--data-dir",
                str(self.data_dir),
                "serve",
                "--host",
                host,
                "--port",
                str(port),
                "--config",
                str(self.config),
                "--ssl-certfile",
                str(cert),
                "--ssl-keyfile",
                str(key),
                "--agent-grace",
                str(grace),
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        deadline = time.monotonic() + 90
        while True:
            try:
                if (
                    httpx.get(
                        f"{self.url}/api/version",
                        verify=ssl.create_default_context(cafile=str(self.ca)),
                        timeout=2,
                    ).status_code
                    == 200
                ):
                    return
            except httpx.HTTPError:
                pass
            assert self.lab.poll() is None, (self.data_dir / "lab.log").read_text(errors="replace")
            assert time.monotonic() < deadline, "the lab did not start"
            time.sleep(0.3)

    def start_agent(
        self, rig: str, spec: str, *, speedup: float = 1.0, netns: str | None = None
    ) -> subprocess.Popen[bytes]:
        secret_file = self.data_dir / f"{rig}.secret"
        secret_file.write_text(
            thermolab(self.data_dir, "agent-secret", rig, "--config", str(self.config))
        )
        log = (self.data_dir / f"agent-{rig}.log").open("ab")
        self.logs.append(log)
        wss = self.agent_url
        prefix = ["ip", "netns", "exec", netns] if netns else []
        process = subprocess.Popen(
            [
                *prefix,
                sys.executable,
                "-m",
                "thermolab",
                "agent",
                "--lab",
                wss,
                "--rig",
                rig,
                "--spec",
                spec,
                "--secret-file",
                str(secret_file),
                "--ca",
                str(self.ca),
                "--outbox",
                str(self.data_dir / f"outbox-{rig}.sqlite3"),
                "--speedup",
                str(speedup),
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        self.others.append(process)
        return process

    def emulator(self) -> str:
        process = subprocess.Popen(
            [sys.executable, "-m", "thermolab.rigs.tclab_emulator", "--seed", "1"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        self.others.append(process)
        assert process.stdout is not None
        line = process.stdout.readline().decode()
        return line.split(" on ", 1)[1].split(" ", 1)[0]

    def client(self, username: str) -> httpx.Client:
        client = httpx.Client(
            base_url=self.url, verify=ssl.create_default_context(cafile=str(self.ca)), timeout=15
        )
        answer = client.post("/api/session", json={"username": username, "password": PASSWORD})
        assert answer.status_code == 200, answer.text
        return client

    def host(self, teacher: httpx.Client, rig: str) -> dict[str, object]:
        hosts = teacher.get("/api/agents").json()
        return next(h for h in hosts if h["rig"] == rig)

    def wait_online(self, teacher: httpx.Client, rig: str, timeout: float = 60) -> float:
        """Wait until the rig is online and healthy (no fault); return the seconds waited."""
        start = time.monotonic()
        while time.monotonic() - start < timeout:
            host = self.host(teacher, rig)
            if host["online"] and host["fault"] is None:
                return time.monotonic() - start
            time.sleep(0.1)
        raise AssertionError(f"rig {rig} not back: {self.host(teacher, rig)}")

    def stop_lab(self) -> None:
        """Stop the lab as its service manager would (SIGTERM), and wait for it."""
        assert self.lab is not None
        self.lab.terminate()
        try:
            self.lab.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.lab.kill()
            self.lab.wait()

    def pause_lab(self) -> None:
        assert self.lab is not None
        self.lab.send_signal(signal.SIGSTOP)

    def resume_lab(self) -> None:
        assert self.lab is not None
        self.lab.send_signal(signal.SIGCONT)

    def stop(self) -> None:
        for process in [*self.others, *([self.lab] if self.lab else [])]:
            if process.poll() is None:
                os.kill(process.pid, signal.SIGCONT)
                process.terminate()
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
            if process.stdout is not None:
                process.stdout.close()
        for log in self.logs:
            log.close()  # type: ignore[attr-defined]


def make_fleet(data_dir: Path, toml: str, extra_ip: str | None = None) -> Fleet:
    config = data_dir / "lab.toml"
    config.write_text(toml, encoding="utf-8")
    ca, cert, key = make_ca(data_dir, extra_ip)
    thermolab(
        data_dir,
        "user",
        "add",
        "tina",
        "--role",
        "admin",
        "--password-stdin",
        "--config",
        str(config),
        stdin=PASSWORD + "\n",
    )
    thermolab(
        data_dir,
        "user",
        "add",
        "ana",
        "--role",
        "student",
        "--password-stdin",
        "--config",
        str(config),
        stdin=PASSWORD + "\n",
    )
    fleet = Fleet(data_dir, config, ca)
    fleet.cert, fleet.key = cert, key  # type: ignore[attr-defined]
    return fleet


class NetNs:
    """A network namespace joined to this one by a veth pair (``ip netns``, ``ip link``).

    ``lab_ip`` is this side's address, ``agent_ip`` the namespace's; :meth:`cut`
    sets this side's end down (the cable pulled), :meth:`mend` up again.
    """

    def __init__(self) -> None:
        tag = f"{os.getpid() % 100000}"
        self.name = f"tl{tag}"
        self.outer = f"tlh{tag}"
        self.inner = f"tla{tag}"
        subnet = os.getpid() % 250 + 1
        self.lab_ip = f"10.213.{subnet}.1"
        self.agent_ip = f"10.213.{subnet}.2"

    @staticmethod
    def permitted() -> str | None:
        """``None`` if namespaces can be made here, else why not."""
        probe = f"tlprobe{os.getpid() % 100000}"
        done = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
        if done.returncode != 0:
            return f"ip netns is not permitted here: {done.stderr.strip()}"
        subprocess.run(["ip", "netns", "del", probe], check=False)
        return None

    def make(self) -> None:
        def ip(*args: str) -> None:
            subprocess.run(["ip", *args], check=True, capture_output=True)

        ip("netns", "add", self.name)
        ip("link", "add", self.outer, "type", "veth", "peer", "name", self.inner)
        ip("link", "set", self.inner, "netns", self.name)
        ip("addr", "add", f"{self.lab_ip}/30", "dev", self.outer)
        ip("link", "set", self.outer, "up")
        ip(
            "netns",
            "exec",
            self.name,
            "ip",
            "addr",
            "add",
            f"{self.agent_ip}/30",
            "dev",
            self.inner,
        )
        ip("netns", "exec", self.name, "ip", "link", "set", self.inner, "up")
        ip("netns", "exec", self.name, "ip", "link", "set", "lo", "up")

    def cut(self) -> None:
        subprocess.run(["ip", "link", "set", self.outer, "down"], check=True)

    def mend(self) -> None:
        subprocess.run(["ip", "link", "set", self.outer, "up"], check=True)

    def remove(self) -> None:
        subprocess.run(["ip", "link", "del", self.outer], capture_output=True, check=False)
        subprocess.run(["ip", "netns", "del", self.name], capture_output=True, check=False)
