"""The rig page's live side, driven message by message through a scripted socket.

The page runs against the real lab (login, rig, access over HTTP) but its
WebSocket is replaced before any script runs by one the test drives, so the
test can send a long run in seconds and cut the connection at will. It checks
what a long session must never do (grow), and what a dropped connection must
do (come back by itself and ask for the gap).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import pytest

pytestmark = pytest.mark.browser

FAKE_SOCKET = """
(() => {
  const sockets = [];
  class FakeSocket {
    constructor(url) {
      this.url = url; this.sent = []; this.readyState = 0;
      sockets.push(this);
    }
    send(data) { this.sent.push(JSON.parse(data)); }
    close(code, reason) {
      this.readyState = 3;
      this.closedWith = code;
    }
  }
  window.WebSocket = FakeSocket;
  window.RUN = 999999;  // a run id the lab does not have (see RUN below)
  window.__sockets = sockets;
  window.__live = {
    open() { const s = sockets[sockets.length - 1]; s.readyState = 1; s.onopen({}); },
    send(msg) { sockets[sockets.length - 1].onmessage({ data: JSON.stringify(msg) }); },
    drop(code) { const s = sockets[sockets.length - 1]; s.readyState = 3;
                 s.onclose({ code: code ?? 1006, reason: '' }); },
  };
})();
"""

K_TRUE, TAU_TRUE = 0.14009, 250.126233
# A run id the lab does not have: the page's history request finds nothing.
RUN = 999_999


@pytest.fixture
def page(lab: Any, logged_in: Any) -> Iterator[Any]:
    context = logged_in("carol", viewport={"width": 1000, "height": 900})
    context.add_init_script(FAKE_SOCKET)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.goto(f"{lab.url}/#/rig/twin-phone")
    pg.wait_for_function("() => window.__sockets.length > 0")
    yield pg
    context.close()
    assert errors == []


def rig_json(page: Any) -> dict[str, Any]:
    rig: dict[str, Any] = page.evaluate("async () => (await fetch('/api/rigs/twin-phone')).json()")
    return rig


def hello(page: Any, seq: int, rig: dict[str, Any], run: dict[str, Any] | None) -> None:
    """Send a hello; with a run going, the page asks once for all the server holds
    (a new socket with ``since=0``): open that one and greet it too."""
    sockets = page.evaluate("() => window.__sockets.length")
    send = (
        "([seq, rig, run]) => "
        "window.__live.send({ type: 'hello', seq, rig, access: rig.access, run })"
    )
    page.evaluate(send, [seq, rig, run])
    if run is not None and run["status"] == "running" and sockets == 1:
        page.wait_for_function(f"() => window.__sockets.length === {sockets + 1}")
        assert page.evaluate("() => window.__sockets[1].url").endswith("/live?since=0")
        page.evaluate("() => window.__live.open()")
        page.evaluate(send, [seq, rig, run])


def run_json(run_id: int, status: str = "running") -> dict[str, Any]:
    return {
        "id": run_id,
        "rig": "twin-phone",
        "status": status,
        "dt": 1.0,
        "nSamples": 20000,
        "signal": "square:0:4:0.1",
        "setpoint": None,
        "methods": [{"method": "wlsm", "gamma": 0.96, "pmax": 10000.0}],
        "samplesStored": 0,
    }


def send_run(page: Any, first_seq: int, n: int, batch: int = 1000) -> int:
    """Send n samples of the twin's square-wave response and a WLSM estimate per sample."""
    return int(
        page.evaluate(
            """([seq, n, batch, K, tau]) => {
              const a = Math.exp(-1 / tau), b = (1 - a) * K;
              let x = 0;
              for (let k0 = 0; k0 < n; k0 += batch) {
                const items = [];
                for (let k = k0; k < Math.min(n, k0 + batch); k++) {
                  const u = Math.floor(k / 5) % 2 ? 0 : 4;
                  items.push({ seq: ++seq, run: RUN, k, t: k, u, y: x });
                  x = a * x + b * u;
                }
                window.__live.send({ type: 'samples', seq, items });
                for (const it of items) {
                  const r = 1 + 0.5 * Math.exp(-it.k / 50);
                  // The first estimates have no first-order meaning (W0 = 0): K and tau null.
                  const valid = it.k >= 20;
                  window.__live.send({ type: 'estimate', seq: ++seq, run: RUN, method: 'wlsm',
                    k: it.k, K: valid ? K * r : null, tau: valid ? tau * r : null, W: [],
                    valid, final: false });
                }
              }
              return seq;
            }""",
            [first_seq, n, batch, K_TRUE, TAU_TRUE],
        )
    )


def drawn(page: Any, label: str) -> int:
    """The chart's points once the redraw asked for so far has run: a chart waits up to
    a tenth of a second between redraws (charts.js REDRAWS_PER_SECOND), so this waits
    for a timer set after its own, then for the frame after its redraw's."""
    page.evaluate(
        """() => new Promise((r) =>
          setTimeout(() => requestAnimationFrame(() => setTimeout(r, 0)), 110))"""
    )
    return int(page.get_attribute(f"figure[aria-label='{label}']", "data-points") or 0)


def assert_axis(page: Any, label: str) -> None:
    """The chart's y axis spans a real range: its lines are drawn."""
    text = page.get_attribute(f"figure[aria-label='{label}']", "data-y-range")
    low, high = (float(v) for v in text.split(","))
    assert math.isfinite(low)
    assert math.isfinite(high)
    assert high > low


def test_a_long_run_keeps_a_fixed_window_and_fixed_memory(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    hello(page, 100, rig, run_json(RUN))
    # Samples before any model: the output chart has a real axis (the model
    # line, NaN for now, must not spoil its range).
    page.evaluate(
        """() => window.__live.send({ type: 'samples', seq: 102, items: [
            { seq: 101, run: RUN, k: 0, t: 0, u: 4, y: 0 },
            { seq: 102, run: RUN, k: 1, t: 1, u: 4, y: 0.1 }] })"""
    )
    # (The page first asks the store for the run's earlier samples; none here.)
    page.wait_for_selector("figure[aria-label^='Output'][data-points='2']")
    assert_axis(page, "Output y and model prediction against time")
    seq = send_run(page, 102, 5000)
    assert drawn(page, "Output y and model prediction against time") == 2000
    # The page's own requests (the rig's card, the run's record) answered first: what
    # they add is drawn once, not counted against the chart (late on a busy machine).
    page.wait_for_load_state("networkidle")
    nodes_before = page.evaluate("() => document.getElementsByTagName('*').length")
    seq = send_run(page, seq, 20000)
    assert drawn(page, "Output y and model prediction against time") == 2000
    assert drawn(page, "Input u against time") == 2000
    # The whole Ks(k) trajectory, decimated to at most 4000 points (+ the newest).
    points = drawn(page, "Ks against sample, Weighted LS (WLSM)")
    assert 2000 <= points <= 4001
    assert_axis(page, "Ks against sample, Weighted LS (WLSM)")
    assert_axis(page, "Output y and model prediction against time")
    page.wait_for_load_state("networkidle")
    nodes_after = page.evaluate("() => document.getElementsByTagName('*').length")
    assert nodes_after == nodes_before
    # The newest estimate is shown as numbers, and the model is drawn over the output.
    ks = float(page.inner_text("[data-panel-view=wlsm] [data-method=wlsm] [data-field=K]"))
    assert math.isclose(ks, K_TRUE, rel_tol=1e-5)
    assert page.input_value("#overlay-method") == "wlsm"
    assert page.evaluate("() => window.__sockets[0].sent.length") >= 0


def test_a_dropped_connection_comes_back_and_asks_for_the_gap(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    hello(page, 10, rig, run_json(RUN))
    seq = send_run(page, 10, 300, batch=100)
    page.evaluate("() => window.__live.drop(1006)")
    page.wait_for_selector("#conn:text('reconnecting')")
    # Backoff with jitter: the first retry comes within a second, asking for what it missed.
    page.wait_for_function("() => window.__sockets.length === 3", timeout=5_000)
    url = page.evaluate("() => window.__sockets[2].url")
    assert url.endswith(f"/api/rigs/twin-phone/live?since={seq}")
    page.evaluate("() => window.__live.open()")
    hello(page, seq + 50, rig, run_json(RUN))
    # The replay overlaps what the page had; the window must hold each sample once.
    page.evaluate(
        """(seq) => window.__live.send({ type: 'samples', seq: seq + 2, items: [
            { seq: seq, run: RUN, k: 299, t: 299, u: 0, y: 1 },
            { seq: seq + 1, run: RUN, k: 300, t: 300, u: 0, y: 1 },
            { seq: seq + 2, run: RUN, k: 301, t: 301, u: 0, y: 1 }] })""",
        seq,
    )
    assert drawn(page, "Output y and model prediction against time") == 302
    page.wait_for_function("() => !document.getElementById('conn').textContent.includes('reconn')")


def test_access_messages_unlock_and_lock_the_controls_live(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    hello(page, 1, rig, None)
    assert page.is_disabled("[data-panel-view=srm-lsm] button[data-action=start]")
    controller = {**rig["access"], "role": "controller", "controller": "carol", "timeLeft": 300}
    page.evaluate(
        "(access) => window.__live.send({ type: 'access', access })",
        controller,
    )
    assert page.is_enabled("[data-panel-view=srm-lsm] button[data-action=start]")
    assert "You have control" in page.evaluate(
        "() => new Promise((r) => setTimeout(() => r(document.getElementById('announce-polite')"
        ".textContent), 100))"
    )
    page.evaluate(
        "() => window.__live.send({ type: 'state', state: 'fault', detail: 'output over 5 V' })"
    )
    assert page.is_disabled("[data-panel-view=srm-lsm] button[data-action=start]")
    assert "fault" in page.inner_text("[data-testid=lock-notice]")
    assert page.inner_text("[data-testid=rig-state]") == "Fault"


def test_joining_half_way_replays_the_runs_history_and_nothing_else(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    hello(page, 500, rig, run_json(RUN))
    # What the server held: the run's samples from the store (no seq), an older
    # run's end and samples, idle readings, this run's estimates; then live.
    page.evaluate(
        """() => {
          window.__live.send({ type: 'samples', items: [0, 1, 2, 3].map((k) =>
            ({ run: RUN, k, t: k, u: 4, y: 0.01 * k })) });
          window.__live.send({ type: 'run', seq: 400, event: 'ended',
            run: { id: 5, status: 'finished', dt: 1, methods: ['srm'], results: {} } });
          window.__live.send({ type: 'sample', seq: 401, run: 5, k: 9, t: 9, u: 0, y: 3 });
          window.__live.send({ type: 'sample', seq: 402, run: null, k: null, t: 1.7e9,
                               u: 0, y: 3 });
          window.__live.send({ type: 'samples', seq: 404, items: [
            { seq: 403, run: RUN, k: 3, t: 3, u: 4, y: 0.03 },
            { seq: 404, run: RUN, k: 4, t: 4, u: 4, y: 0.04 }] });
          window.__live.send({ type: 'estimate', seq: 405, run: RUN, method: 'wlsm', k: 4,
            K: 0.2, tau: 300, W: [], valid: true, final: false });
          window.__live.send({ type: 'sample', seq: 501, run: RUN, k: 5, t: 5, u: 4, y: 0.05 });
        }"""
    )
    assert drawn(page, "Output y and model prediction against time") == 6
    assert page.inner_text("[data-testid=run-status-wlsm]").startswith(f"Run #{RUN} running")
    assert (
        page.inner_text("[data-panel-view=wlsm] [data-method=wlsm] [data-field=K]") == "0.200000"
    )  # six decimals, as the paper prints
    assert "Run 5" not in page.inner_text("[data-testid=chart-note]")


def test_a_watcher_sees_the_controllers_countdown(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    watcher = {**rig["access"], "role": "watcher", "controller": "dave", "timeLeft": 125}
    hello(page, 1, {**rig, "access": watcher}, None)
    assert page.inner_text("[data-testid=access-role]") == "You are watching (read-only)."
    assert page.inner_text("dt[data-for=timeLeft]") == "Controller's time left"
    first = page.inner_text("[data-field=timeLeft]")
    assert first in ("2:05", "2:04")
    # It counts down on the page, between access messages.
    page.wait_for_function(
        "(t) => document.querySelector('[data-field=timeLeft]').textContent !== t",
        arg=first,
        timeout=3_000,
    )
    assert page.inner_text("[data-field=timeLeft]") in ("2:04", "2:03")
    assert page.is_disabled("[data-panel-view=srm-lsm] button[data-action=start]")
    # Nobody at the controls: no countdown.
    page.evaluate(
        "(access) => window.__live.send({ type: 'access', access })",
        {**watcher, "controller": None, "timeLeft": None},
    )
    assert page.inner_text("[data-field=timeLeft]") == "–"


def test_an_estimate_without_a_model_says_why(page: Any) -> None:
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    run = {
        **run_json(RUN),
        "operatingPoint": {
            "asked": "auto",
            "used": "fit",
            "reason": "fit: the constant term is estimated with the model",
        },
    }
    hello(page, 50, rig, run)
    assert page.inner_text("[data-testid=operating-point-wlsm]").startswith(
        "Operating point: fit: the constant term is estimated with the model"
    )
    reason = "unstable or integrating model: a pole on or outside the unit circle (a >= 1)"
    page.evaluate(
        """(reason) => window.__live.send({ type: 'estimate', seq: 51, run: RUN,
             method: 'wlsm', k: 3, K: null, tau: null, W: [1.02, 0.001, 0.0], valid: false,
             final: false, reason })""",
        reason,
    )
    status = "[data-panel-view=wlsm] [data-method=wlsm] [data-field=status]"
    page.wait_for_function(
        "(sel) => document.querySelector(sel).textContent.startsWith('live: ')", arg=status
    )
    assert page.inner_text(status) == f"live: {reason}"
    assert page.inner_text("[data-panel-view=wlsm] [data-method=wlsm] [data-field=K]") == "–"


def test_a_truncated_replay_of_a_long_run_still_fills_the_window(page: Any) -> None:
    """Joining a long run, the server sends its first sample, a `truncated` notice and the
    newest samples (docs/live-protocol.md, "Replay"): the window shows the newest."""
    page.evaluate("() => window.__live.open()")
    rig = rig_json(page)
    hello(page, 10, rig, run_json(RUN))
    page.evaluate(
        """() => {
          window.__live.send({ type: 'samples', items: [{ run: RUN, k: 0, t: 0, u: 4, y: -5 }] });
          window.__live.send({ type: 'truncated', run: RUN, from: 15001, limit: 5000 });
          for (let k0 = 15001; k0 < 20000; k0 += 1000) {
            const items = [];
            for (let k = k0; k < Math.min(20000, k0 + 1000); k++) {
              items.push({ run: RUN, k, t: k, u: 4, y: 0.5 + 1e-5 * k });
            }
            window.__live.send({ type: 'samples', items });
          }
          window.__live.send({ type: 'sample', seq: 11, run: RUN, k: 20000, t: 20000, u: 4,
                               y: 0.7 });
        }"""
    )
    label = "Output y and model prediction against time"
    assert drawn(page, label) == 2000
    low, high = (
        float(v)
        for v in page.get_attribute(f"figure[aria-label='{label}']", "data-y-range").split(",")
    )
    # The newest samples, not the first one's -5.
    assert low > 0.5
    assert high < 1
    # ... and the page says so, offering the whole record.
    notice = page.inner_text("[data-testid=chart-truncated]")
    assert f"Run {RUN} is too long to replay here whole" in notice
    assert "from sample 15001 on (at most 5000 samples" in notice
    href = page.get_attribute("[data-testid=chart-truncated-csv]", "href")
    assert href == f"/api/runs/{RUN}/samples.csv"
