"""Live charts of the browser interface on a phone-class CPU: cost per redraw and per burst.

Runs in the system Chromium (``/usr/bin/chromium``, through Playwright) with the
CPU slowed down 4x through the DevTools protocol, the factor Lighthouse uses to
stand for a mid-range phone. The interface's way (``thermolab.web``: a
``RingBuffer`` of 2000 rows whose time-ordered columns are zero-copy views, and
a redraw at most once per animation frame) is measured beside a peer written
the common way: plain arrays with ``push``/``shift`` and a synchronous
``setData`` for every sample. Both draw the same uPlot charts (output and
model, input) of a 2000-sample window.

Figures:

* redraw of a full 2000-sample window (averaged): the cost of one
  frame at 10 samples/s; the budget of a 60 Hz frame is 16.7 ms;
* main-thread busy time (DevTools' TaskDuration: scripts, style, paint) per
  second of live data at 10 samples/s with one estimate per sample (a
  recursive method): at each sample instant two socket messages back to back,
  each its own task, in real time. Ours redraws at most once per animation
  frame, the peer on every message; headless Chromium runs a frame as soon as
  one is asked for, so here the two messages often fall in separate frames
  and the coalescing shows less than on a 60 Hz screen.

Usage::

    .venv/bin/python benchmarks/bench_web_charts.py [--throttle 4] [--repeat 200]
"""

from __future__ import annotations

import argparse
import functools
import http.server
import threading
from typing import Any

from thermolab.web import STATIC_DIR

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

PAGE_JS = """
async ({ repeat }) => {
  const { RingBuffer } = await import('/js/ring.js');
  const { Chart } = await import('/js/charts.js');
  const { predict } = await import('/js/model.js');
  const W = 2000;
  const host = document.body;
  host.style.width = '360px';
  const frame = () => new Promise((r) => requestAnimationFrame(() => r()));
  const sample = (k) => ({ t: k, u: Math.floor(k / 300) % 2 ? 10 : 0, y: Math.sin(k / 200) });
  const model = { K: 0.14009, tau: 250.126233 };

  // Ours: ring buffer, zero-copy views, model recomputed into a reused array.
  const ring = new RingBuffer(W, ['t', 'u', 'y']);
  const yhat = new Float64Array(W);
  const oursData = () => {
    const t = ring.column('t'), u = ring.column('u'), y = ring.column('y');
    return [t, y, predict(u, y[0] ?? 0, model, 1, yhat)];
  };
  const oursOut = new Chart(host, { label: 'o', xLabel: 't', yLabel: 'y', source: oursData,
    series: [{ label: 'y' }, { label: 'model' }] });
  const oursIn = new Chart(host, { label: 'i', xLabel: 't', yLabel: 'u', height: 160,
    source: () => [ring.column('t'), ring.column('u')], series: [{ label: 'u' }] });

  // Peer: plain arrays, shift() past the window, setData on every sample.
  const arr = { t: [], u: [], y: [] };
  const peerData = () => {
    const yh = Array.from(predict(arr.u, arr.y[0] ?? 0, model, 1));
    return [arr.t.slice(), arr.y.slice(), yh];
  };
  const peerOut = new Chart(host, { label: 'po', xLabel: 't', yLabel: 'y', source: peerData,
    series: [{ label: 'y' }, { label: 'model' }] });
  const peerIn = new Chart(host, { label: 'pi', xLabel: 't', yLabel: 'u', height: 160,
    source: () => [arr.t.slice(), arr.u.slice()], series: [{ label: 'u' }] });
  const peerPush = (s) => {
    for (const c of ['t', 'u', 'y']) { arr[c].push(s[c]); if (arr[c].length > W) arr[c].shift(); }
    peerOut.draw(); peerIn.draw();
  };

  for (let k = 0; k < W; k++) {
    ring.push(sample(k));
    for (const c of ['t', 'u', 'y']) arr[c].push(sample(k)[c]);
  }
  await frame();
  // uPlot paints in a microtask after setData: time up to the end of it.
  const settled = () => Promise.resolve();
  window.bench = {
    // One full-window redraw of both charts, averaged over `repeat`.
    async redraw(which) {
      const t0 = performance.now();
      for (let i = 0; i < repeat; i++) {
        if (which === 'ours') { ring.push(sample(W + i)); oursOut.draw(); oursIn.draw(); }
        else peerPush(sample(W + i));
        await settled();
      }
      return (performance.now() - t0) / repeat;
    },
    // `seconds` of live data at 10 samples/s: at each sample instant the sample
    // and its estimate (a recursive method) arrive back to back, each its own
    // task as off a socket, then nothing for 100 ms. Ours only marks the charts
    // dirty; the peer redraws on each message.
    async live(which, seconds) {
      const task = (ms) => new Promise((r) => setTimeout(r, ms));
      for (let i = 0; i < 10 * seconds; i++) {
        const k = 3 * W + i;
        if (which === 'ours') {
          ring.push(sample(k)); oursOut.invalidate(); oursIn.invalidate();
          await task(0);
          oursOut.invalidate();  // the estimate moves the model line
        } else {
          peerPush(sample(k));
          await task(0);
          peerOut.draw();
        }
        await task(100);
      }
      await frame();
    },
  };
  return +oursOut.el.dataset.points;
}
"""


class _Quiet(http.server.SimpleHTTPRequestHandler):
    extensions_map = {  # noqa: RUF012 - the base class declares a plain dict
        **http.server.SimpleHTTPRequestHandler.extensions_map,
        ".js": "text/javascript",
    }

    def log_message(self, format: str, *args: Any) -> None:
        pass


def _task_seconds(cdp: Any) -> float:
    """The page's main-thread busy time so far (DevTools' TaskDuration), in seconds."""
    metrics = cdp.send("Performance.getMetrics")["metrics"]
    return float(next(m["value"] for m in metrics if m["name"] == "TaskDuration"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--throttle", type=float, default=4.0, help="CPU slow-down (4: phone)")
    parser.add_argument("--repeat", type=int, default=200, help="redraws to average")
    parser.add_argument("--seconds", type=int, default=10, help="seconds of live data")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    handler = functools.partial(_Quiet, directory=str(STATIC_DIR))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 375, "height": 800})
            page.goto(f"{url}/css/app.css")
            page.evaluate(
                "() => { document.body.innerHTML = ''; const l = document.createElement('link');"
                " l.rel = 'stylesheet'; l.href = '/vendor/uplot/uPlot.min.css';"
                " document.head.append(l); }"
            )
            cdp = page.context.new_cdp_session(page)
            cdp.send("Emulation.setCPUThrottlingRate", {"rate": args.throttle})
            cdp.send("Performance.enable")
            points = page.evaluate(PAGE_JS, {"repeat": args.repeat})
            r = {"points": points}
            for which in ("ours", "peer"):
                r[f"{which}Redraw"] = page.evaluate("w => window.bench.redraw(w)", which)
            for which in ("ours", "peer"):
                before = _task_seconds(cdp)
                page.evaluate("([w, s]) => window.bench.live(w, s)", [which, args.seconds])
                r[f"{which}Busy"] = (_task_seconds(cdp) - before) * 1000 / args.seconds
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
    print(f"Chromium, CPU throttled {args.throttle:g}x, 375 px, window {r['points']} samples")
    print(f"{'':44} {'ours':>10} {'peer':>10} {'peer/ours':>10}")
    rows = [
        ("one full-window redraw, both charts (ms)", r["oursRedraw"], r["peerRedraw"]),
        ("main thread per second of live data (ms)", r["oursBusy"], r["peerBusy"]),
    ]
    for name, ours, peer in rows:
        print(f"{name:44} {ours:10.2f} {peer:10.2f} {peer / ours:10.1f}")
    budget = 1000 / 60
    print(
        f"target: a redraw within a 60 Hz frame ({budget:.1f} ms): "
        f"{'met' if r['oursRedraw'] < budget else 'NOT met'}; "
        f"live data at 10 samples/s keeps the main thread busy "
        f"{r['oursBusy'] / 10:.1f} % of the time"
    )


if __name__ == "__main__":
    main()
