"""Unit tests of the interface's JavaScript modules, run in a real Chromium.

Each test imports modules from the static folder (served over HTTP, no lab
behind it) and checks their behaviour: the ring buffers that bound memory, the
live client's reconnection and gap filling (against a scripted WebSocket and
fake timers, so nothing waits), input checking, the model arithmetic, and the
run request each panel builds.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from thermolab.web import STATIC_DIR

pytestmark = pytest.mark.browser


def run_js(page: Any, body: str) -> Any:
    """Run an async function body in the page and return its (JSON) result."""
    return page.evaluate(f"async () => {{ {body} }}")


def test_every_module_loads(module_page: Any) -> None:
    modules = sorted(
        "/" + p.relative_to(STATIC_DIR).as_posix()
        for p in (STATIC_DIR / "js").rglob("*.js")
        if p.name != "app.js"
    )
    assert "/js/views/rig.js" in modules
    failed = run_js(
        module_page,
        f"""
        const out = [];
        for (const m of {modules!r}) {{
          try {{ await import(m); }} catch (e) {{ out.push(m + ': ' + e); }}
        }}
        return out;
        """,
    )
    assert failed == []


def test_ring_buffer_keeps_the_newest_rows_in_order_in_fixed_memory(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { RingBuffer } = await import('/js/ring.js');
        const rb = new RingBuffer(5, ['t', 'y']);
        const bytes = () => [...rb._cols.values()].reduce((s, c) => s + c.byteLength, 0);
        const before = bytes();
        const empty = [...rb.column('t')];
        for (let i = 0; i < 3; i++) rb.push({ t: i, y: 10 * i });
        const partial = [...rb.column('t')];
        for (let i = 3; i < 100003; i++) rb.push({ t: i, y: 10 * i });
        const view = rb.column('y');
        const out = {
          empty, partial, t: [...rb.column('t')], y: [...view], length: rb.length,
          last: rb.last('t'), sameMemory: bytes() === before,
          isView: view.buffer === rb._cols.get('y').buffer,
        };
        rb.push({ t: 100003 });  // missing column -> NaN
        out.missing = Number.isNaN(rb.last('y'));
        rb.setColumn('y', [1, 2]);
        out.set = [...rb.column('y')].slice(-2);
        rb.clear();
        out.cleared = rb.length;
        let threw = false;
        try { new RingBuffer(0, ['t']); } catch (e) { threw = e instanceof RangeError; }
        out.threw = threw;
        return out;
        """,
    )
    assert r["empty"] == []
    assert r["partial"] == [0, 1, 2]
    assert r["t"] == [99998, 99999, 100000, 100001, 100002]
    assert r["y"] == [10 * t for t in r["t"]]
    assert r["length"] == 5
    assert r["last"] == 100002
    assert r["sameMemory"] is True
    assert r["isView"] is True
    assert r["missing"] is True
    assert r["set"] == [1, 2]
    assert r["cleared"] == 0
    assert r["threw"] is True


def test_decimating_buffer_bounds_a_whole_trajectory(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { DecimatingBuffer } = await import('/js/ring.js');
        const b = new DecimatingBuffer(100, ['k', 'K']);
        for (let k = 0; k < 100000; k++) b.push({ k, K: k / 10 });
        const k = [...b.column('k')];
        const K = [...b.column('K')];
        let sorted = true;
        for (let i = 1; i < k.length; i++) if (!(k[i] > k[i - 1])) sorted = false;
        return { n: k.length, first: k[0], last: k[k.length - 1], lastK: K[K.length - 1],
                 sorted, stride: b.stride, cap: b._cols.get('k').length,
                 evenlySpaced: k.slice(0, -1).every((v, i) => v === i * b.stride) };
        """,
    )
    assert r["n"] <= 101  # capacity plus the newest offered row
    assert r["n"] >= 50
    assert r["first"] == 0
    assert r["last"] == 99999
    assert r["lastK"] == pytest.approx(9999.9)
    assert r["sorted"] is True
    assert r["evenlySpaced"] is True
    assert r["cap"] == 100


def test_backoff_grows_exponentially_with_jitter_and_a_cap(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { backoffDelay } = await import('/js/live.js');
        const at = (random) => [0, 1, 2, 3, 10, 40].map(
          (a) => backoffDelay(a, { baseMs: 500, maxMs: 15000, random }));
        const lo = at(() => 0);
        const hi = at(() => 0.999999);
        return { lo, hi };
        """,
    )
    assert_allclose(r["lo"], [250, 500, 1000, 2000, 7500, 7500])
    assert_allclose(r["hi"], [500, 1000, 2000, 4000, 15000, 15000], rtol=1e-5)


# A scripted WebSocket and manual timers: the live client is driven step by step.
FAKES = """
const sockets = [];
class FakeWS {
  constructor(url) { this.url = url; this.sent = []; this.closed = null; sockets.push(this); }
  send(d) { this.sent.push(JSON.parse(d)); }
  close(code, reason) { this.closed = { code, reason }; }
  open() { this.onopen && this.onopen({}); }
  msg(o) { this.onmessage && this.onmessage({ data: JSON.stringify(o) }); }
  drop(code = 1006) { this.onclose && this.onclose({ code, reason: '' }); }
}
let now = 0;
let timers = [];
let nextId = 1;
const T = {
  setTimeout(fn, ms) { const id = nextId++; timers.push({ id, at: now + ms, fn }); return id; },
  clearTimeout(id) { timers = timers.filter((t) => t.id !== id); },
};
function advance(ms) {
  const end = now + ms;
  for (;;) {
    timers.sort((a, b) => a.at - b.at);
    const t = timers[0];
    if (!t || t.at > end) break;
    timers.shift();
    now = t.at;
    t.fn();
  }
  now = end;
}
const got = [];
const statuses = [];
const { LiveClient } = await import('/js/live.js');
const client = new LiveClient('rig-1', {
  onMessage: (m) => got.push(m),
  onStatus: (s) => statuses.push(
    s.state + (s.delayMs !== undefined ? ':' + Math.round(s.delayMs) : '')),
}, {
  WebSocketImpl: FakeWS, timers: T, now: () => now, random: () => 0.5,
  url: (rig, since) => rig + (since === null ? '' : '?since=' + since),
  pingMs: 5000, baseMs: 1000, maxMs: 8000,
});
"""


def test_live_client_fills_the_gap_after_a_drop_and_drops_duplicates(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        const s0 = sockets[0];
        s0.open();
        s0.msg({ type: 'hello', seq: 10, rig: {}, access: {}, run: null });
        s0.msg({ type: 'sample', seq: 11, k: 0, t: 0, u: 1, y: 2, run: 7 });
        s0.msg({ type: 'sample', seq: 12, k: 1, t: 1, u: 1, y: 2, run: 7 });
        s0.drop();                       // network gone
        const waiting = statuses[statuses.length - 1];
        advance(749);
        const before = sockets.length;
        advance(1);                      // the retry fires (1000 ms nominal, 750 with jitter 0.5)
        const s1 = sockets[1];
        s1.open();
        s1.msg({ type: 'hello', seq: 15, rig: {}, access: {}, run: null });
        // The replay overlaps what we had (seq 12) and fills 13..15.
        s1.msg({ type: 'samples', seq: 14, items: [
          { seq: 12, k: 1, t: 1, u: 1, y: 2, run: 7 },
          { seq: 13, k: 2, t: 2, u: 1, y: 2, run: 7 },
          { seq: 14, k: 3, t: 3, u: 1, y: 2, run: 7 }] });
        s1.msg({ type: 'estimate', seq: 15, run: 7, method: 'wlsm', k: 3, K: 1, tau: 2 });
        s1.msg({ type: 'estimate', seq: 15, run: 7, method: 'wlsm', k: 3, K: 1, tau: 2 });
        s1.msg({ type: 'access', access: { role: 'watcher' } });  // not part of the stream
        return { urls: sockets.map((s) => s.url), waiting, before, statuses,
                 seqs: got.map((m) => m.type + ':' + (m.seq ?? '-')), lastSeq: client.lastSeq,
                 attempt: client.attempt };
        """,
    )
    assert r["urls"] == ["rig-1", "rig-1?since=12"]
    assert r["waiting"] == "waiting:750"
    assert r["before"] == 1
    assert r["seqs"] == [
        "hello:10",
        "sample:11",
        "sample:12",
        "hello:15",
        "sample:13",
        "sample:14",
        "estimate:15",
        "access:-",
    ]
    assert r["lastSeq"] == 15
    assert r["attempt"] == 0


def test_live_client_backs_off_while_the_server_is_down(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        for (let i = 0; i < 6; i++) { sockets[sockets.length - 1].drop(); advance(60000); }
        return statuses.filter((s) => s.startsWith('waiting'));
        """,
    )
    # 1000 * 2^n capped at 8000, times 0.75 (equal jitter with random 0.5).
    assert r == [
        "waiting:750",
        "waiting:1500",
        "waiting:3000",
        "waiting:6000",
        "waiting:6000",
        "waiting:6000",
    ]


def test_live_client_pings_and_treats_a_silent_link_as_dead(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        const s0 = sockets[0];
        s0.open();
        s0.msg({ type: 'hello', seq: 1, rig: {}, access: {}, run: null });
        advance(5000);
        const pings = s0.sent.length;
        s0.msg({ type: 'pong' });
        advance(5000);
        const pings2 = s0.sent.length;
        // Now the server goes silent (half-open TCP): no close event ever comes.
        advance(20000);
        return { pings, pings2, closed: s0.closed, sockets: sockets.length,
                 second: sockets[1] && sockets[1].url, sent: s0.sent[0] };
        """,
    )
    assert r["pings"] == 1
    assert r["pings2"] == 2
    assert r["sent"] == {"type": "ping"}
    assert r["closed"]["code"] == 4000
    assert r["sockets"] == 2
    assert r["second"] == "rig-1?since=1"


def test_live_client_gives_up_on_unauthorized_and_stops_cleanly(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        sockets[0].drop(4401);
        advance(60000);
        const afterAuth = { n: sockets.length, state: client.state, timers: timers.length };
        const c2 = new LiveClient('r', { onMessage() {} },
                                  { WebSocketImpl: FakeWS, timers: T, now: () => now });
        c2.start();
        sockets[sockets.length - 1].open();
        c2.stop();
        const closed = sockets[sockets.length - 1].closed;
        return { afterAuth, stoppedTimers: timers.length, closed };
        """,
    )
    assert r["afterAuth"] == {"n": 1, "state": "closed", "timers": 0}
    assert r["stoppedTimers"] == 0
    assert r["closed"]["code"] == 1000


def test_number_checks_refuse_bad_values_with_the_allowed_range(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { checkNumber, rangeText } = await import('/js/validate.js');
        const u = { label: 'Set point', min: -10, max: 10, unit: 'V' };
        const n = { label: 'Number of samples', min: 10, max: 100000, integer: true };
        const g = { label: 'γ', min: 0, max: 1, exclusiveMin: true, exclusiveMax: true };
        const cases = [['5', u], [' -2.5 ', u], ['−3', u], ['1e1', u], ['10.01', u], ['', u],
                       ['abc', u], ['0x10', u], ['NaN', u], ['Infinity', u], ['2000', n],
                       ['2000.5', n], ['5', n], ['0.96', g], ['1', g], ['0', g], ['3,5', u]];
        return { results: cases.map(([t, s]) => checkNumber(t, s)),
                 range: rangeText(u), grange: rangeText(g),
                 // A set point below the output limit, a gain with no bounds: never "−Infinity".
                 below: rangeText({ label: 'r', min: -Infinity, max: 5, exclusiveMax: true,
                                    unit: 'V' }),
                 any: rangeText({ label: 'x', min: -Infinity, max: Infinity }),
                 runs: rangeText({ label: 'run', min: 1, max: Infinity, integer: true }) };
        """,
    )
    assert (r["below"], r["any"], r["runs"]) == (
        "less than 5 V",
        "any number",
        "an integer at least 1",
    )
    res = r["results"]
    assert res[0] == {"ok": True, "value": 5}
    assert res[1] == {"ok": True, "value": -2.5}
    assert res[2] == {"ok": True, "value": -3}
    assert res[3] == {"ok": True, "value": 10}
    assert res[4]["ok"] is False
    assert "−10 to 10 V" in res[4]["error"]
    assert "10.01" in res[4]["error"]
    assert "required" in res[5]["error"]
    for bad in res[6:10]:
        assert bad["ok"] is False
        assert "number" in bad["error"]
    assert res[10] == {"ok": True, "value": 2000}
    assert "whole number" in res[11]["error"]
    assert res[12]["ok"] is False
    assert res[13] == {"ok": True, "value": 0.96}
    assert res[14]["ok"] is False
    assert res[15]["ok"] is False
    assert res[16] == {"ok": True, "value": 3.5}
    assert r["range"] == "−10 to 10 V"
    assert r["grange"] == "more than 0 and less than 1"


def test_model_arithmetic_matches_eq_4(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const m = await import('/js/model.js');
        const d = m.toDiscrete(0.14009, 250.126233, 1);
        const back = m.fromDiscrete(d.a, d.b, 1);
        const w0 = m.fromDiscrete(m.PAPER_W0.a, m.PAPER_W0.b, 1);
        const u = new Float64Array(3000).fill(10);
        const y = m.predict(u, 0.5, { K: 0.14009, tau: 250.126233 }, 1);
        const y2 = m.predict([10, 10], 0.5, { K: 2, tau: 1 }, 1, undefined, 1);
        return {
          a: d.a, b: d.b, back, w0, y0: y[0], y1: y[1], yEnd: y[2999],
          y2: [...y2], none: m.fromDiscrete(1.2, 0.1, 1),
          base: [m.predictionBase('initial', [0.99, 0.001], 0.5),
                 m.predictionBase(undefined, null, 0.5),
                 m.predictionBase('fit', [0.99, 0.001, 0.002], 0.5),
                 m.predictionBase('fit', [1.2, 0.001, 0.002], 0.5),
                 m.predictionBase('none', [0.99, 0.001], 0.5),
                 m.predictionBase(2.5, [0.99, 0.001], 0.5)],
          fmt: [m.fmt(0.1400901234), m.fmt(250.126233), m.fmt(NaN), m.fmt(1e-6, 3)],
        };
        """,
    )
    import math

    a = math.exp(-1 / 250.126233)
    assert_allclose([r["a"], r["b"]], [a, (1 - a) * 0.14009], rtol=1e-14)
    assert_allclose([r["back"]["K"], r["back"]["tau"]], [0.14009, 250.126233], rtol=1e-12)
    assert_allclose([r["w0"]["K"], r["w0"]["tau"]], [0.0269905, 26.73742], rtol=2e-6)
    assert r["y0"] == 0.5
    assert_allclose(r["y1"], 0.5 + (1 - a) * 0.14009 * 10, rtol=1e-14)
    assert_allclose(r["yEnd"], 0.5 + 1.4009 * (1 - a**2999), rtol=1e-12)
    a2 = math.exp(-1)
    assert_allclose(r["y2"], [1.5, 0.5 + a2 + (1 - a2) * 20], rtol=1e-14)
    assert r["none"] is None
    # The level a model is drawn about: the first output, or the fitted ambient c / (1 - a).
    assert_allclose(r["base"], [0.5, 0.5, 0.2, 0.5, 0.0, 2.5], rtol=1e-12)
    assert r["fmt"] == ["0.14009", "250.126", "–", "1.00e-6"]


def test_each_panel_builds_its_run_request(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        (await import('/js/methods.js')).useMethods(SERVED);  // the panels' methods
        const { buildRunSpec, automaticSignal, panelOfRun } = await import('/js/runspec.js');
        const p1 = buildRunSpec({ id: 'srm-lsm' }, { dt: 1, n: 2000, setpoint: 0, block: 0 },
                                false);
        const p1b = buildRunSpec({ id: 'srm-lsm' }, { dt: 1, n: 2000, low: 4, high: 6, block: 100 },
                                 true);
        const p2 = buildRunSpec({ id: 'malsm' },
                                { dt: 0.5, n: 500, window: 100, low: 4, high: 6 }, true);
        const w = { dt: 1, n: 3000, gamma: 0.96, pmax: 1e4, a0: 0.96329, b0: 9.9082e-4,
                    low: 0, high: 4 };
        const p3 = buildRunSpec({ id: 'wlsm' }, w, true);
        const p3w0 = buildRunSpec({ id: 'wlsm' }, w, true, { w0: true });
        const p3fit = buildRunSpec({ id: 'wlsm' }, { ...w, offset: 'fit' }, true,
                                   { w0: true, offset: true });
        const p2old = buildRunSpec({ id: 'malsm' },
                                   { dt: 1, n: 500, window: 100, low: 4, high: 6, offset: 'fit' },
                                   true);
        // The pair chosen (a kit): sent when it is not the standard one.
        const p1pair = buildRunSpec({ id: 'srm-lsm' },
                                    { dt: 1, n: 20, setpoint: 50, block: 0, pair: 'q2>t2' }, false);
        const p1std = buildRunSpec({ id: 'srm-lsm' },
                                   { dt: 1, n: 20, setpoint: 50, block: 0, pair: 'u>y' }, false);
        return { p1, p1b, p2, p3, p3w0, p3fit, p2old, p1pair, p1std,
                 sig: automaticSignal(4, 6, 1),
                 panels: [panelOfRun(p1), panelOfRun(p2), panelOfRun(p3)] };
        """.replace("SERVED", _served_methods()),
    )
    assert r["sig"] == "square:4:6:0.1"
    assert r["p1"] == {"dt": 1, "samples": 2000, "setpoint": 0, "methods": ["srm", "lsm"]}
    assert r["p1b"] == {
        "dt": 1,
        "samples": 2000,
        "signal": "square:4:6:0.1",
        "methods": ["srm", "lsm", "blockls"],
        "block": 100,
    }
    assert r["p2"] == {
        "dt": 0.5,
        "samples": 500,
        "signal": "square:4:6:0.2",
        "methods": ["malsm"],
        "window": 100,
    }
    assert r["p3"] == {
        "dt": 1,
        "samples": 3000,
        "signal": "square:0:4:0.1",
        "methods": ["wlsm"],
        "gamma": 0.96,
        "pmax": 1e4,
    }
    assert r["p3w0"]["w0"] == [0.96329, 9.9082e-4]
    assert (r["p1pair"]["input"], r["p1pair"]["output"]) == ("q2", "t2")
    assert "input" not in r["p1std"]
    assert "output" not in r["p1std"]
    assert (r["p3fit"]["offset"], r["p3fit"]["w0"]) == ("fit", [0.96329, 9.9082e-4])
    assert "offset" not in r["p2old"]  # a server whose schema has no offset is not sent one
    assert r["panels"] == ["srm-lsm", "malsm", "wlsm"]


def test_ranges_are_read_from_the_servers_schema(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { numericRange, hasProperty, enumValues } = await import('/js/schema.js');
        const { rangeText } = await import('/js/validate.js');
        const doc = { components: { schemas: { RunIn: { properties: {
          dt: { type: 'number', exclusiveMinimum: 0, maximum: 3600 },
          samples: { type: 'integer', minimum: 1, maximum: 200000 },
          pmax: { anyOf: [{ type: 'number', exclusiveMinimum: 0 }, { type: 'null' }] },
          signal: { anyOf: [{ type: 'string' }, { type: 'null' }] },
          offset: { anyOf: [{ type: 'string', enum: ['auto', 'initial', 'fit', 'none'] },
                            { type: 'number' }], default: 'auto' } } } } } };
        const dt = numericRange(doc, 'RunIn', 'dt');
        const samples = numericRange(doc, 'RunIn', 'samples');
        const pmax = numericRange(doc, 'RunIn', 'pmax');
        return { dt, samples, pmax, none: numericRange(doc, 'RunIn', 'signal'),
                 missing: numericRange(doc, 'RunIn', 'w0'), w0: hasProperty(doc, 'RunIn', 'w0'),
                 offsets: enumValues(doc, 'RunIn', 'offset'),
                 noOffsets: enumValues(doc, 'RunIn', 'signal'),
                 texts: [rangeText({ ...dt, unit: 's' }), rangeText(samples), rangeText(pmax)] };
        """,
    )
    assert r["dt"] == {"integer": False, "min": 0, "exclusiveMin": True, "max": 3600}
    assert r["samples"] == {"integer": True, "min": 1, "max": 200000}
    assert r["pmax"] == {"integer": False, "min": 0, "exclusiveMin": True}
    assert r["none"] is None
    assert r["missing"] is None
    assert r["w0"] is False
    assert r["offsets"] == ["auto", "initial", "fit", "none"]
    assert r["noOffsets"] is None
    assert r["texts"] == [
        "more than 0 and at most 3600 s",
        "an integer from 1 to 200000",
        "more than 0",
    ]


def test_csv_and_error_messages_are_read_as_the_server_sends_them(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { parseCsv } = await import('/js/csv.js');
        const { errorMessage } = await import('/js/api.js');
        const text = 't,u,y,jitter\\r\\n0,0,0.5,0\\n1,10,0.51,\\n\\n2,10,x,0\\n';
        const t = parseCsv(text, ['k', 't', 'u', 'y']);
        return {
          k: [...t.k], y: [...t.y].map((v) => Number.isNaN(v) ? null : v),
          e1: errorMessage({ detail: 'rig is in use' }, 'x'),
          e2: errorMessage({ detail: [{ loc: ['body', 'dt'], msg: 'must be > 0' },
                                      { loc: ['body', 'methods', 0, 'gamma'],
                                        msg: 'too big' }] }, 'x'),
          e3: errorMessage(null, '500 Internal Server Error'),
        };
        """,
    )
    assert r["k"] == [0, 1, 2]
    assert r["y"] == [0.5, 0.51, None]
    assert r["e1"] == "rig is in use"
    assert r["e2"] == "dt: must be > 0; methods.0.gamma: too big"
    assert r["e3"] == "500 Internal Server Error"


def test_table_figures_are_the_servers_own(module_page: Any) -> None:
    """The comparison reads the statistics the lab stored (thermolab.ident's Trajectory.stats
    and converged_at), and computes none itself."""
    from thermolab.ident.online import make_identifier
    from thermolab.lab.runs import json_safe, method_statistics
    from thermolab.simulation import REFERENCE_MODEL

    rng = np.random.default_rng(7)
    u = np.where((np.arange(3000) // 5) % 2 == 0, 4.0, 0.0)
    y = REFERENCE_MODEL.simulate(u) + rng.normal(0, 1e-5, u.size)
    ident = make_identifier("wlsm", 1.0, gamma=0.96, pmax=1e4, w0=[0.96329, 9.9082e-4])
    estimates = [ident.update(uk, yk) for uk, yk in zip(u, y, strict=True)]
    latest = ident.finish()
    assert latest is not None
    stats = json_safe(method_statistics("wlsm", ident, latest.to_dict()))
    stored = {
        "latest": latest.to_dict(),
        "trajectory": {  # for the charts only: deliberately not what the stats came from
            "k": [e.k for e in estimates[:50] if e is not None],
            "K": [0.5] * 50,
            "tau": [10.0] * 50,
            "valid": [True] * 50,
        },
        "stats": stats,
    }
    r = run_js(
        module_page,
        f"""
        const {{ readResult }} = await import('/js/results.js');
        const f = readResult({json.dumps(stored)}, 'wlsm');
        return {{ K: f.K, tau: f.tau, conv: f.convergedAt, converges: f.converges,
                 valid: f.valid, last: f.last, W: f.final.W, points: f.trajectory.k.length,
                 running: readResult({{ latest: {{ K: 0.14, tau: 250, valid: true, W: [0.99, 1e-3],
                   extras: {{ warnings: ['short record'] }} }} }}, 'malsm'),
                 lsm: readResult({{ latest: {{ K: 0.14, tau: 250, valid: true }},
                   stats: {{ last: 2000, tol: 0.01, K: {{ mean: 0.14, max: 0.14, min: 0.14 }},
                   tau: {{ mean: 250, max: 250, min: 250 }}, converged_at: null }} }}, 'lsm'),
                 invalid: readResult({{ latest: {{ K: null, tau: null, valid: false,
                   extras: {{ reason: 'not excited' }} }},
                   stats: {{ K: null, tau: null, converged_at: {{ K: null, tau: null }} }} }},
                   'malsm') }};
        """,
    )
    for name in ("K", "tau"):
        assert r[name] == stats[name]
    assert r["conv"] == stats["converged_at"]
    assert r["conv"]["K"] is not None
    # The statistics cover the samples after convergence (thermolab identify's rule).
    assert stats["last"] == 3000 - 1 - max(stats["converged_at"].values())
    assert (r["converges"], r["valid"], r["last"], r["points"]) == (True, True, stats["last"], 50)
    assert r["W"] == list(latest.W)
    # A run still going: only its latest estimate, no statistics, no convergence yet.
    assert r["running"]["K"] == {"mean": 0.14, "max": 0.14, "min": 0.14}
    assert r["running"]["converges"] is False
    assert r["running"]["warnings"] == ["short record"]
    assert r["lsm"]["converges"] is False
    assert r["lsm"]["tau"] == {"mean": 250, "max": 250, "min": 250}
    assert r["invalid"]["valid"] is False
    assert r["invalid"]["reason"] == "not excited"
    assert (r["invalid"]["K"], r["invalid"]["converges"]) == (None, True)
    assert r["invalid"]["convergedAt"] == {"K": None, "tau": None}


def test_live_client_replays_everything_and_marks_the_history(module_page: Any) -> None:
    r = run_js(
        module_page,
        FAKES
        + """
        client.start();
        sockets[0].open();
        sockets[0].msg({ type: 'hello', seq: 10, rig: {}, access: {}, run: { id: 3 } });
        client.replayAll();
        const s1 = sockets[1];
        s1.open();
        s1.msg({ type: 'hello', seq: 12, rig: {}, access: {}, run: { id: 3 } });
        s1.msg({ type: 'samples', items: [{ run: 3, k: 0 }, { run: 3, k: 1 }] });
        s1.msg({ type: 'run', seq: 6, event: 'ended', run: { id: 2 } });
        s1.msg({ type: 'estimate', seq: 12, run: 3, k: 1 });
        s1.msg({ type: 'access', access: {} });
        s1.msg({ type: 'sample', seq: 13, run: 3, k: 2 });
        s1.msg({ type: 'samples', items: [{ run: 3, k: 3 }] });
        const show = (m) => `${m.type}:${m.seq ?? '-'}:${m.history ? 'h' : 'live'}`;
        return { url: s1.url, closed: sockets[0].closed, got: got.slice(1).map(show) };
        """,
    )
    assert r["url"] == "rig-1?since=0"
    assert r["closed"]["code"] == 1000
    assert r["got"] == [
        "hello:12:live",
        "sample:-:h",
        "sample:-:h",
        "run:6:h",
        "estimate:12:h",
        "access:-:live",
        "sample:13:live",
        "sample:-:live",
    ]


def test_messages_fill_placeholders_pick_plurals_and_fall_back_to_english(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { durationWords } = await import('/js/dom.js');
        const out = {
          started: i18n.t('run.started', { run: 12 }),
          missingParam: i18n.t('run.started'),
          unknown: i18n.t('no.such.key'),
          none: i18n.t('lobby.waiting', { count: 0 }),
          one: i18n.t('lobby.waiting', { count: 1 }),
          many: i18n.t('lobby.waiting', { count: 1234 }),
          words: [durationWords(61), durationWords(120), durationWords(1)],
          lang: i18n.language(),
        };
        // A language with its own plural rules and number form; keys it lacks stay English.
        i18n.setLanguage('pt-BR', {
          'lobby.waiting': { one: '{count} aguardando', other: '{count} aguardando' },
          'run.started': 'Ensaio {run} iniciado.',
        });
        out.pt = {
          started: i18n.t('run.started', { run: 12 }),
          zeroFallsToOther: i18n.t('lobby.waiting', { count: 0 }),
          many: i18n.t('lobby.waiting', { count: 1234.5 }),
          english: i18n.t('lobby.none'),
          number: i18n.formatNumber(0.5),
          htmlLang: document.documentElement.lang,
        };
        i18n.setLanguage('en', (await import('/js/messages/en.js')).messages);
        return out;
        """,
    )
    assert r["started"] == "Run 12 started."
    assert r["missingParam"] == "Run {run} started."
    assert r["unknown"] == "no.such.key"
    assert r["none"] == "empty"
    assert r["one"] == "1 waiting"
    assert r["many"] == "1,234 waiting"
    assert r["words"] == ["1 minute 1 second", "2 minutes", "1 second"]
    assert r["lang"] == "en"
    assert r["pt"]["started"] == "Ensaio 12 iniciado."
    assert r["pt"]["zeroFallsToOther"] == "0 aguardando"
    assert r["pt"]["many"] == "1.234,5 aguardando"
    assert r["pt"]["english"] == "The lab has no rigs."
    assert r["pt"]["number"] == "0,5"
    assert r["pt"]["htmlLang"] == "pt-BR"


def _served_methods() -> str:
    """The body of GET /api/methods, as JSON text for a page."""
    from thermolab.lab.http.routers.methods import list_methods

    return json.dumps(list_methods(), allow_nan=False)


PANELS_FROM_SERVED_METHODS = """
    const m = await import('/js/methods.js');
    const { panelOfRun, methodTitle } = await import('/js/runspec.js');
    const { panelDefinitions, panelLimits } = await import('/js/views/panels/definitions.js');
    const field = (defs, panel, name) =>
      defs.find((d) => d.id === panel).fields.find((f) => f.name === name);
    const served = SERVED;
    m.useMethods(served);
    const defs = panelDefinitions(panelLimits(null, null));
    const pick = (f) => ({ min: f.min, max: f.max, value: f.value,
                           exclusiveMin: !!f.exclusiveMin, exclusiveMax: !!f.exclusiveMax });
    const out = {
      methods: defs.map((d) => d.methods),
      window: pick(field(defs, 'malsm', 'window')),
      gamma: pick(field(defs, 'wlsm', 'gamma')),
      pmax: pick(field(defs, 'wlsm', 'pmax')),
      a0b0: [field(defs, 'wlsm', 'a0').value, field(defs, 'wlsm', 'b0').value],
      trajectory: ['srm', 'malsm', 'wlsm#2'].map(m.hasTrajectory),
      panel: panelOfRun({ methods: ['srm', 'lsm', 'blockls'] }),
    };
    let refused = '';
    try { m.useMethods({ methods: [{ title: 'x' }] }); } catch (e) { refused = e.name; }
    out.refused = refused;
    const more = JSON.parse(JSON.stringify(served));
    more.methods.push({ name: 'rls', title: 'Recursive LS', panel: 3,
                        returns: ['trajectory'], settings: [] });
    m.useMethods(more);
    const after = panelDefinitions(panelLimits(null, null));
    out.added = {
      wlsmMethods: after.find((d) => d.id === 'wlsm').methods,
      panel: panelOfRun({ methods: ['rls'] }),
      title: methodTitle('rls'),
      trajectory: m.hasTrajectory('rls'),
    };
    m.useMethods(served);
    return out;
"""


def test_panels_take_their_methods_from_get_api_methods(module_page: Any) -> None:
    """Panels are built from GET /api/methods: the registry and the lab's run ranges."""
    from thermolab.ident.registry import SETTINGS, get_method
    from thermolab.lab.runs.request import RUN_SETTINGS

    r = run_js(module_page, PANELS_FROM_SERVED_METHODS.replace("SERVED", _served_methods()))
    assert r["methods"] == [["srm", "lsm", "blockls", "oe"], ["malsm"], ["wlsm"]]

    def expected(name: str) -> dict[str, Any]:
        s = RUN_SETTINGS[name]
        return {
            "min": s.minimum,
            "max": s.maximum,
            "value": s.default,
            "exclusiveMin": s.exclusive_minimum,
            "exclusiveMax": s.exclusive_maximum,
        }

    assert r["window"] == expected("window")
    assert r["gamma"] == expected("gamma")  # the lab's narrowing: gamma < 1
    assert r["gamma"]["exclusiveMax"] is True
    assert r["pmax"]["min"] == 0
    assert r["pmax"]["value"] == SETTINGS["pmax"].default
    assert r["a0b0"] == list(SETTINGS["w0"].default)
    assert r["trajectory"] == [
        "trajectory" in get_method(n).returns for n in ("srm", "malsm", "wlsm")
    ]
    assert r["panel"] == "srm-lsm"
    assert r["refused"] == "TypeError"
    assert r["added"] == {
        "wlsmMethods": ["wlsm", "rls"],
        "panel": "wlsm",
        "title": "Recursive LS",
        "trajectory": True,
    }


def test_the_librarys_warnings_and_reasons_read_in_the_pages_language(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const i18n = await import('/js/i18n.js');
        const { identReason, identWarning } = await import('/js/identwords.js');
        const said = (node) => typeof node === 'string' ? { text: node, english: [] }
          : { text: node.textContent,
              english: [...node.querySelectorAll('[lang=en]')].map((el) => el.textContent),
              marked: node.getAttribute('lang') };
        const show = () => ({
          warning: said(identWarning(
            'final estimate: implausible gain: K = -1 has the wrong sign')),
          timing: said(identWarning(
            'timing jitter: the sample period spreads 12 % around its median')),
          unknown: said(identWarning('something new: details')),
          reason: said(identReason('no step: the input stays at 2.5 V for the whole record')),
          pole: said(identReason(
            'dominant pole <= 0: a sampled first-order lag has 0 < a < 1')),
          other: said(identReason('a = 1.2 >= 1: the identified model is unstable')),
        });
        const en = show();
        i18n.setLanguage('pt-BR', (await import('/js/messages/pt-BR.js')).messages);
        const pt = show();
        i18n.setLanguage('en', (await import('/js/messages/en.js')).messages);
        return { en, pt };
        """,
    )
    en, pt = r["en"], r["pt"]
    # English: the kind, ADVICE's line, then the library's detail.
    assert en["timing"]["text"] == (
        "timing jitter: samples were not evenly spaced, which biases methods that assume one "
        "period; unload the machine or take a longer sample period, and re-record (the sample "
        "period spreads 12 % around its median)"
    )
    assert en["warning"]["text"].startswith("final estimate: implausible gain: the gain has")
    assert en["warning"]["english"] == []
    assert en["unknown"]["text"] == "something new: details"
    assert en["reason"]["text"] == "no step: the input stays at 2.5 V for the whole record"
    # Portuguese: the kind and the advice translated, only the detail marked as English.
    assert pt["warning"]["text"].startswith("estimativa final: ganho implausível: o ganho tem")
    assert pt["warning"]["english"] == ["K = -1 has the wrong sign"]
    assert pt["warning"]["text"].endswith("(K = -1 has the wrong sign)")
    assert pt["timing"]["text"].startswith("variação no período de amostragem: as amostras")
    assert pt["timing"]["english"] == ["the sample period spreads 12 % around its median"]
    assert pt["reason"]["text"] == "sem degrau: the input stays at 2.5 V for the whole record"
    assert pt["reason"]["english"] == ["the input stays at 2.5 V for the whole record"]
    assert pt["pole"]["text"].startswith("polo dominante ≤ 0: a sampled")
    # A kind the page does not know is shown as the server wrote it, marked as English.
    assert pt["unknown"] == {"text": "something new: details", "english": [], "marked": "en"}
    assert pt["other"]["marked"] == "en"
