"""Fixtures for the browser interface's tests: a headless Chromium, the static files, a lab.

Browser tests use the system Chromium through Playwright: Debian's headless shell
(``/usr/bin/chromium-headless-shell``, the build Playwright's own headless mode uses)
where it is installed, else the full browser (``/usr/bin/chromium``); the variable
``THERMOLAB_CHROMIUM`` names another. They never download a browser. Where either is
missing they skip and say why.

The end-to-end tests run a real lab as a teacher would: ``thermolab --data-dir
DIR serve --config lab.toml --port PORT --speedup X`` in a subprocess, so they
exercise the shipped command, the real app and the twin rigs, with nothing
mocked. Its accounts are made in this process, through the same service
``thermolab user add`` calls, on the lab's own database (the command itself is
tested by tests/lab/test_cli.py): a process per account, each importing the lab
and hashing at production cost, took most of a lab's start.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from argon2 import PasswordHasher

from thermolab.web import STATIC_DIR

from .page_diary import DIARY, keep_diary, start_diary

# The headless shell ran the same browser tests in about 30 % less CPU than the full
# browser's headless mode (tests/web/test_e2e.py and test_phone_layout.py: 54 -> 37
# CPU-s, wall 111 -> 79 s): CI is CPU-bound on two cores (issue #20).
HEADLESS_SHELL = Path("/usr/bin/chromium-headless-shell")
CHROMIUM = Path(
    os.environ.get("THERMOLAB_CHROMIUM")
    or (HEADLESS_SHELL if HEADLESS_SHELL.is_file() else "/usr/bin/chromium")
)
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"


def browser_skip_reason() -> str | None:
    """Why browser tests cannot run here, or None when they can."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright for Python is not installed (pip install playwright)"
    if not (CHROMIUM.is_file() and os.access(CHROMIUM, os.X_OK)):
        found = shutil.which("chromium")
        return f"no Chromium at {CHROMIUM} ({'found ' + found if found else 'none on PATH'})"
    return None


PAGE_DEADLINE_MS = 90_000
"""How long a page's wait (a selector, a function, a click) may take before it fails.

Each wait ends at its event; the deadline only says when to give up. Playwright's
30 s ran out on a rig page's first draw on a loaded machine (both cores busy,
several browsers and servers beside it), so the pages get the time the servers'
own deadlines give them.
"""


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """A headless system Chromium, shared by the session's browser tests."""
    reason = browser_skip_reason()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        plain_new_context = chromium.new_context

        def new_context(**options: Any) -> Any:
            context = plain_new_context(**options)
            context.set_default_timeout(PAGE_DEADLINE_MS)
            return keep_diary(context)

        chromium.new_context = new_context  # type: ignore[method-assign]
        try:
            yield chromium
        finally:
            chromium.close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {  # noqa: RUF012 - the base class declares it a plain dict
        **http.server.SimpleHTTPRequestHandler.extensions_map,
        ".js": "text/javascript",
        ".css": "text/css",
    }

    def log_message(self, format: str, *args: Any) -> None:
        pass


@pytest.fixture(scope="session")
def static_url() -> Iterator[str]:
    """The interface's static folder served over HTTP (no lab behind it)."""
    handler = functools.partial(_QuietHandler, directory=str(STATIC_DIR))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


@pytest.fixture(scope="module")
def _module_context(browser: Any, static_url: str) -> Iterator[tuple[Any, list[str]]]:
    context = browser.new_context()
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(f"{static_url}/css/app.css")
    try:
        yield page, errors
    finally:
        context.close()


@pytest.fixture
def module_page(_module_context: tuple[Any, list[str]]) -> Iterator[Any]:
    """A page on the static server's origin, ready to import the interface's modules.

    One page serves a whole test module (each test imports what it needs inside
    its own function scope); a test fails if it left an uncaught error behind.
    """
    page, errors = _module_context
    errors.clear()
    yield page
    assert errors == [], f"uncaught errors in the page: {errors}"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    """On a browser test's failure, say what each open page showed and what its lab logged.

    A failure seen once in a full CI run (a page that never showed a state) cannot be
    rerun: this section of the report is all that is left of it.
    """
    if call.when == "setup":
        start_diary()
    report = yield
    funcargs = getattr(item, "funcargs", {})
    if report.when == "call" and report.failed and "browser" in funcargs:
        with contextlib.suppress(Exception):
            report.sections.append(("what the pages showed", _pages_now(funcargs)))
        diary = "\n".join(f"{at:7.2f} s  page {page}: {what}" for at, page, what in DIARY)
        report.sections.append(("what the pages did (tests/web/page_diary.py)", diary))
    return report


def _pages_now(funcargs: dict[str, Any]) -> str:
    """Each open page's address and start of its text; the session lab's log tail."""
    lines: list[str] = []
    for context in funcargs["browser"].contexts:
        for page in context.pages:
            text = page.evaluate("() => document.body ? document.body.innerText : ''")
            lines.append(f"{page.url}: {' | '.join(text.split(chr(10)))[:800]}")
            errors = getattr(page, "errors", None)  # what tests record of uncaught errors
            if errors:
                lines.append(f"  uncaught errors in that page: {errors}")
    servers = [v for v in funcargs.values() if isinstance(v, LabServer)]
    servers += [  # fixtures that yield (lab, something)
        x for v in funcargs.values() if isinstance(v, tuple) for x in v if isinstance(x, LabServer)
    ]
    for server in servers:
        if server.log.exists():
            log = server.log.read_text(encoding="utf-8", errors="replace")
            lines.append(f"--- the lab's log ({server.url}), last lines ---")
            lines.extend(log.splitlines()[-40:])
    return "\n".join(lines)


@pytest.fixture(scope="session")
def artifacts() -> Path:
    """Folder for screenshots (git-ignored)."""
    ARTIFACTS.mkdir(exist_ok=True)
    return ARTIFACTS


# -- a running lab ------------------------------------------------------------------------

# Twin rigs run this many times faster than real time: a 2000-sample run at
# T = 1 s takes 2000 / SPEEDUP seconds.
SPEEDUP = 200.0

USERS = {
    "alice": "student",
    "bob": "student",
    "carol": "student",
    "dave": "student",
    "erin": "student",
    "fran": "student",
    "lucia": "student",
    "pia": "student",
    "tess": "teacher",
}

# One rig per test that takes control, so the tests do not depend on each other's order.
CONFIG = """\
title = "ThermoLab e2e"

[[rigs]]
id = "twin"
title = "Digital twin of the paper's box"
spec = "sim"

[[rigs]]
id = "twin-keys"
title = "Twin for the keyboard test"
spec = "sim"

[[rigs]]
id = "twin-phone"
title = "Twin for the phone test"
spec = "sim"

[[rigs]]
id = "twin-lang"
title = "Twin for the language tests"
spec = "sim"

[[rigs]]
id = "twin-loop"
title = "Kit twin for the PID test"
spec = "sim:tclab"

[[rigs]]
id = "twin-fan"
title = "Twin for the hand-over test"
spec = "sim"
"""


def password(user: str) -> str:
    """The test password of a user."""
    return f"pw-{user}-0123-lab"


class LabServer:
    """A running ``thermolab serve``: its URL and data folder; it can be restarted."""

    def __init__(
        self,
        data_dir: Path,
        port: int,
        env: dict[str, str],
        speedup: float = SPEEDUP,
        serve_options: tuple[str, ...] = (),
    ) -> None:
        self.data_dir = data_dir
        self.serve_options = serve_options
        self.port = port
        self.speedup = speedup
        self.url = f"http://127.0.0.1:{port}"
        self.log = data_dir / "server.log"
        self._env = env
        self._proc: subprocess.Popen[bytes] | None = None

    def password(self, user: str) -> str:
        """The password ``user`` was created with."""
        return password(user)

    def start(self) -> None:
        """Start the server (appending to its log) without waiting for it."""
        with self.log.open("a", encoding="utf-8") as out:
            self._proc = subprocess.Popen(
                _thermolab(
                    self.data_dir,
                    "serve",
                    "--config",
                    str(self.data_dir / "lab.toml"),
                    "--port",
                    str(self.port),
                    "--speedup",
                    str(self.speedup),
                    *self.serve_options,
                ),
                stdout=out,
                stderr=subprocess.STDOUT,
                env=self._env,
            )

    def wait_until_up(self) -> None:
        """Wait until the server answers (an unauthenticated 401)."""
        assert self._proc is not None
        _wait_until_up(self.url, self._proc, self.log)

    def kill(self) -> None:
        """Kill the server at once (SIGKILL), as a crash or a power cut would."""
        if self._proc is None:
            return
        self._proc.kill()
        self._proc.wait(5)
        self._proc = None

    def stop(self) -> None:
        """Stop the server as a supervisor would (SIGTERM, then SIGKILL)."""
        if self._proc is None:
            return
        self._proc.terminate()
        try:
            self._proc.wait(15)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait(5)
        self._proc = None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _thermolab(data_dir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "thermolab", "--data-dir", str(data_dir), *args]


@contextlib.contextmanager
def running_lab(
    data_dir: Path,
    users: dict[str, str] = USERS,
    *,
    config: str = CONFIG,
    speedup: float = SPEEDUP,
    serve_options: tuple[str, ...] = (),
) -> Iterator[LabServer]:
    """Create the users, start ``thermolab serve``, wait until it answers; stop it after.

    ``config`` is the lab's TOML file, ``speedup`` its ``--speedup`` (twins only) and
    ``serve_options`` further options of ``thermolab serve``.
    """
    (data_dir / "lab.toml").write_text(config, encoding="utf-8")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    add_accounts(data_dir, users)
    server = LabServer(data_dir, _free_port(), env, speedup, serve_options)
    server.start()
    try:
        server.wait_until_up()
        yield server
    finally:
        server.stop()


# Argon2 at its cheapest: the server verifies any hash by the parameters stored in it.
CHEAP_HASHER = PasswordHasher(time_cost=1, memory_cost=8, parallelism=1)


def add_accounts(data_dir: Path, users: dict[str, str]) -> None:
    """Make the lab's database (migrated) and its accounts, as ``thermolab user add`` does."""
    from thermolab.lab.accounts.users import UserService
    from thermolab.lab.clock import SystemClock
    from thermolab.lab.config import load_config
    from thermolab.lab.db import Database

    config = load_config(data_dir / "lab.toml", data_dir)
    db = Database(config.database, pool_size=1, max_overflow=1)
    try:
        db.upgrade()
        accounts = UserService(db, SystemClock(), CHEAP_HASHER)
        for user, role in users.items():
            # The browser journeys' teachers run the whole lab (accounts, rigs, LTI).
            accounts.add(user, password(user), role, admin=role == "teacher")
    finally:
        db.close()


def _wait_until_up(url: str, proc: subprocess.Popen[bytes], log: Path) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(
                f"thermolab serve exited with {proc.returncode}:\n{log.read_text()[-3000:]}"
            )
        try:
            urllib.request.urlopen(f"{url}/api/session", timeout=2).close()
            return
        except urllib.error.HTTPError as exc:
            if exc.code == 401:  # up, and refusing us as it should
                return
        except OSError:
            pass
        time.sleep(0.2)  # real time: waiting for a process to start, not simulated time
    raise RuntimeError(f"thermolab serve did not answer within 60 s:\n{log.read_text()[-3000:]}")


_LOGINS: dict[tuple[str, str], Any] = {}


def audited(page: Any, actor: str) -> set[tuple[str, str]]:
    """(action, target) of ``actor``'s rows of the audit log, read by ``page`` (an
    administrator's) with one request: what a journey's privileged actions left."""
    status, rows = page.evaluate(
        """async (actor) => {
          const answer = await fetch(`/api/audit?actor=${encodeURIComponent(actor)}`);
          return [answer.status, await answer.json()];
        }""",
        actor,
    )
    assert status == 200, rows
    return {(row["action"], row["target"]) for row in rows}


def logged_in_context(browser: Any, lab: LabServer, user: str, **options: Any) -> Any:
    """A new browser context already logged in as ``user``.

    The first time, the user logs in through the login form; later contexts
    reuse that session's cookie (as a second tab would), which spares a
    password hash per test.
    """
    # By lab and user: a browser sends 127.0.0.1's cookies to every port, so a session
    # of one lab's "ana" reused on another lab's page was a stranger there (the page
    # stayed on its login form, in whichever module met "ana" second in a worker).
    key = (lab.url, user)
    if key not in _LOGINS:
        context = browser.new_context()
        page = context.new_page()
        page.goto(f"{lab.url}/")
        page.fill("#login-username", user)
        page.fill("#login-password", lab.password(user))
        page.click("form button[type=submit]")
        page.wait_for_selector("#nav:not([hidden])")
        _LOGINS[key] = context.storage_state()
        context.close()
    return browser.new_context(storage_state=_LOGINS[key], **options)


@pytest.fixture(scope="session")
def lab(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[LabServer]:
    """A lab with three twin rigs and the users of USERS, for the whole session."""
    with running_lab(tmp_path_factory.mktemp("lab")) as server:
        yield server


@pytest.fixture
def logged_in(browser: Any, lab: LabServer) -> Any:
    """``logged_in(user, **context_options)`` -> a new context logged in as ``user``."""
    return functools.partial(logged_in_context, browser, lab)


@pytest.fixture
def own_lab(tmp_path: Path, browser: Any) -> Iterator[LabServer]:
    """A lab of its own (one student), for a test that stops and restarts it."""
    with running_lab(tmp_path, {"sam": "student"}) as server:
        yield server


@pytest.fixture(scope="session")
def start_lab() -> Any:
    """``start_lab(data_dir, users, config=..., speedup=..., serve_options=...)``: a lab of a
    test's own making.

    The context manager of :func:`running_lab`, for a module that needs another
    configuration (its own rigs, another speed-up).
    """
    return running_lab


@pytest.fixture(scope="session")
def context_for(browser: Any) -> Any:
    """``context_for(lab, user, **context_options)`` -> a new context logged in to ``lab``."""
    return functools.partial(logged_in_context, browser)
