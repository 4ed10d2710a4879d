"""Speed of the identification methods, beside peers measured in the same run.

Run from the repository root::

    .venv/bin/python benchmarks/bench_ident.py            # 10^6 samples
    .venv/bin/python benchmarks/bench_ident.py --samples 200000 --repeat 2

Every method of :mod:`thermolab.ident` is timed on the same record (the
reference model driven by the paper's 4↔6 V square wave at 0.1 Hz, with 1 mV of
seeded measurement noise so that no window is degenerate); the batch LSM also
on the paper's 2000 samples, in microseconds. Times are the best of several
runs of the public function, input checks and the ``(K, tau)`` conversion
included, after a warm-up call (Numba compiles on first use).

Peers:

* padasip's ``FilterRLS`` (a pure-NumPy RLS filter): run on a subset and
  scaled, since it is slow;
* a scalar C loop of the same two recursions, exponential-forgetting RLS and
  the moving-window running-sum solve, written below, compiled with
  ``cc -O2`` into a temporary folder and called through ctypes (skipped with a
  message when no C compiler is found). Like ours it stores ``W``, ``K`` and
  ``tau`` at every sample, so the two produce the same arrays (checked).

The table gives samples per second and the throughput ratios ours / padasip
and ours / C (above 1: ours is faster). Targets (issue #2): WLSM and MALSM at
least 100x padasip and within 3x of C (ratio >= 0.33); batch LSM on 2000
samples well under 1 ms.
"""

from __future__ import annotations

import argparse
import ctypes
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from thermolab.ident import (
    block_least_squares,
    least_squares,
    moving_window_least_squares,
    step_response,
    weighted_least_squares,
)
from thermolab.signals import Square, Step
from thermolab.simulation import PAPER_W0, REFERENCE_MODEL

GAMMA, PMAX, WINDOW, BLOCK = 0.96, 1e4, 100, 100

C_SOURCE = r"""
#include <math.h>

/* Like thermolab's methods, every estimate is also converted to (K, tau). */
static void to_first_order(double a, double b, double dt, double *K, double *tau)
{
    if (a > 0.0 && a < 1.0 && isfinite(b)) {
        *K = b / (1.0 - a);
        *tau = -dt / log(a);
    } else {
        *K = NAN;
        *tau = NAN;
    }
}

/* Exponential-forgetting RLS, first order: D(k) = [y[k], u[k]], target y[k+1].
   W is n x 2; row 0 holds W0, row k+1 the estimate after the row of sample k. */
void rls2(const double *u, const double *y, long n, double gamma, double p0,
          double a, double b, double dt, double *W, double *K, double *tau)
{
    double P00 = p0, P01 = 0.0, P11 = p0;
    W[0] = a; W[1] = b;
    to_first_order(a, b, dt, &K[0], &tau[0]);
    for (long k = 0; k + 1 < n; ++k) {
        double x0 = y[k], x1 = u[k];
        double Px0 = P00 * x0 + P01 * x1, Px1 = P01 * x0 + P11 * x1;
        double den = gamma + x0 * Px0 + x1 * Px1;
        double g0 = Px0 / den, g1 = Px1 / den;
        double e = y[k + 1] - (a * x0 + b * x1);
        a += g0 * e;
        b += g1 * e;
        P00 = (P00 - g0 * Px0) / gamma;
        P01 = (P01 - g0 * Px1) / gamma;
        P11 = (P11 - g1 * Px1) / gamma;
        W[2 * (k + 1)] = a;
        W[2 * (k + 1) + 1] = b;
        to_first_order(a, b, dt, &K[k + 1], &tau[k + 1]);
    }
}

/* Moving-window least squares over the last `rows` regression rows, running sums
   of D'D and D'Y with the leaving row subtracted, recomputed exactly every `rows`
   rows; 2x2 solve by Cramer's rule. W row k: estimate whose newest target is y[k]. */
void malsm2(const double *u, const double *y, long n, long rows, double dt,
            double *W, double *K, double *tau)
{
    double s00 = 0.0, s01 = 0.0, s11 = 0.0, r0 = 0.0, r1 = 0.0;
    long since = 0;
    for (long k = 0; k < n && k < rows; ++k) {
        W[2 * k] = NAN; W[2 * k + 1] = NAN; K[k] = NAN; tau[k] = NAN;
    }
    for (long j = 0; j + 1 < n; ++j) {
        double x0 = y[j], x1 = u[j], t = y[j + 1];
        s00 += x0 * x0; s01 += x0 * x1; s11 += x1 * x1; r0 += x0 * t; r1 += x1 * t;
        if (j >= rows) {
            long i = j - rows;
            double z0 = y[i], z1 = u[i], v = y[i + 1];
            s00 -= z0 * z0; s01 -= z0 * z1; s11 -= z1 * z1; r0 -= z0 * v; r1 -= z1 * v;
        }
        if (++since >= rows && j + 1 >= rows) {
            s00 = s01 = s11 = r0 = r1 = 0.0;
            for (long i = j + 1 - rows; i <= j; ++i) {
                double z0 = y[i], z1 = u[i], v = y[i + 1];
                s00 += z0 * z0; s01 += z0 * z1; s11 += z1 * z1; r0 += z0 * v; r1 += z1 * v;
            }
            since = 0;
        }
        if (j + 1 >= rows) {
            double det = s00 * s11 - s01 * s01, a = NAN, b = NAN;
            if (det > 1e-12 * s00 * s11) {
                a = (r0 * s11 - r1 * s01) / det;
                b = (s00 * r1 - s01 * r0) / det;
            }
            W[2 * (j + 1)] = a;
            W[2 * (j + 1) + 1] = b;
            to_first_order(a, b, dt, &K[j + 1], &tau[j + 1]);
        }
    }
}
"""


def best_of(fn: Callable[[], Any], repeat: int) -> float:
    """Best wall time of ``repeat`` calls, in seconds."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def compile_c(folder: Path) -> ctypes.CDLL | str:
    """Compile :data:`C_SOURCE`; return the library or the reason it is unavailable."""
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        return "no C compiler (cc, gcc or clang) on PATH"
    src, lib = folder / "peer.c", folder / "libpeer.so"
    src.write_text(C_SOURCE)
    proc = subprocess.run(
        [cc, "-O2", "-shared", "-fPIC", "-o", str(lib), str(src)],
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        return f"{cc} failed: {proc.stderr.strip().splitlines()[-1:]}"
    dll = ctypes.CDLL(str(lib))
    arr = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    dll.rls2.argtypes = [arr, arr, ctypes.c_long, *[ctypes.c_double] * 5, arr, arr, arr]
    dll.rls2.restype = None
    dll.malsm2.argtypes = [arr, arr, ctypes.c_long, ctypes.c_long, ctypes.c_double, arr, arr, arr]
    dll.malsm2.restype = None
    return dll


def record(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The reference model under the 4↔6 V square wave, with 1 mV of seeded noise."""
    t = np.arange(n, dtype=np.float64)
    u = Square(4.0, 6.0, 0.1).sample(t)
    y = REFERENCE_MODEL.simulate(u) + np.random.default_rng(1).normal(0.0, 1e-3, n)
    return u, y


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="record length")
    parser.add_argument("--repeat", type=int, default=3, help="runs per method (best kept)")
    parser.add_argument(
        "--padasip-samples", type=int, default=20_000, help="padasip subset, scaled up"
    )
    args = parser.parse_args(argv)
    n = args.samples
    u, y = record(n)
    dt = 1.0

    # Warm-up: Numba compiles (or loads its cache) on first use.
    u_small, y_small = u[:5000], y[:5000]
    moving_window_least_squares(u_small, y_small, dt, WINDOW)
    weighted_least_squares(u_small, y_small, dt, GAMMA, PMAX, PAPER_W0, offset="none")
    block_least_squares(u_small, y_small, dt, BLOCK)
    least_squares(u_small, y_small, dt)

    t_step = np.arange(n, dtype=np.float64)
    u_step = Step(0.0, 10.0, at=1.0).sample(t_step)
    y_step = REFERENCE_MODEL.simulate(u_step) + np.random.default_rng(2).normal(0.0, 1e-3, n)

    def srm() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            step_response(t_step, u_step, y_step)

    ours: dict[str, float] = {
        "lsm": best_of(lambda: least_squares(u, y, dt), args.repeat),
        "blockls": best_of(lambda: block_least_squares(u, y, dt, BLOCK), args.repeat),
        "malsm": best_of(lambda: moving_window_least_squares(u, y, dt, WINDOW), args.repeat),
        "wlsm": best_of(
            lambda: weighted_least_squares(u, y, dt, GAMMA, PMAX, PAPER_W0, offset="none"),
            args.repeat,
        ),
        "srm": best_of(srm, args.repeat),
    }
    u2k, y2k = u[:2000], y[:2000]
    lsm_2000 = best_of(lambda: least_squares(u2k, y2k, dt), 200)

    # padasip: the same regression rows, forgetting factor, P0 = 1/eps.
    import padasip as pa

    m = min(args.padasip_samples, n - 1)
    x_rows = np.column_stack([y[:m], u[:m]])
    targets = y[1 : m + 1]

    def padasip_rls() -> None:
        pa.filters.FilterRLS(
            n=2, mu=GAMMA, eps=1.0 / ((1 - GAMMA) * PMAX), w=np.array(PAPER_W0)
        ).run(targets, x_rows)

    padasip_rate = m / best_of(padasip_rls, 2)

    c_rates: dict[str, float] = {}
    c_check: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        lib = compile_c(Path(tmp))
        if isinstance(lib, str):
            print(f"C peer skipped: {lib}")
        else:
            W, K, tau = np.empty((n, 2)), np.empty(n), np.empty(n)
            p0 = (1 - GAMMA) * PMAX  # the paper's pmax as a standard initial covariance
            c_rates["wlsm"] = n / best_of(
                lambda: lib.rls2(u, y, n, GAMMA, p0, *PAPER_W0, dt, W, K, tau), args.repeat
            )
            ref = weighted_least_squares(u, y, dt, GAMMA, PMAX, PAPER_W0, offset="none").W
            c_check["wlsm"] = float(np.nanmax(np.abs(W[1:] - ref[1:]) / np.abs(ref[1:])))
            c_rates["malsm"] = n / best_of(
                lambda: lib.malsm2(u, y, n, WINDOW - 1, dt, W, K, tau), args.repeat
            )
            ref = moving_window_least_squares(u, y, dt, WINDOW, offset="none").W
            ok = np.isfinite(ref[:, 0]) & np.isfinite(W[:, 0])
            c_check["malsm"] = float(np.max(np.abs(W[ok] - ref[ok]) / np.abs(ref[ok])))

    print(f"thermolab.ident on {n:,} samples (best of {args.repeat}); padasip on {m:,}, scaled")
    print()
    head = f"{'method':<26}{'time':>12}{'samples/s':>14}{'ours/padasip':>14}{'ours/C':>10}"
    print(head)
    print("-" * len(head))
    names = {
        "lsm": "LSM (batch)",
        "blockls": f"LSM blocks of {BLOCK}",
        "malsm": f"MALSM window {WINDOW}",
        "wlsm": f"WLSM γ={GAMMA}",
        "srm": "SRM (step response)",
    }
    for key, seconds in ours.items():
        rate = n / seconds
        vs_pa = f"{rate / padasip_rate:,.0f}x" if key in ("malsm", "wlsm") else ""
        vs_c = f"{rate / c_rates[key]:.2f}" if key in c_rates else ""
        print(f"{names[key]:<26}{seconds * 1e3:>10.1f} ms{rate:>14.3g}{vs_pa:>14}{vs_c:>10}")
    print(f"{'padasip FilterRLS':<26}{'':>12}{padasip_rate:>14.3g}")
    for key, label in (("wlsm", "C scalar RLS"), ("malsm", "C moving window")):
        if key in c_rates:
            print(f"{label:<26}{n / c_rates[key] * 1e3:>10.1f} ms{c_rates[key]:>14.3g}")
    print()
    print(f"LSM on 2000 samples (best of 200): {lsm_2000 * 1e6:.0f} µs")
    for key, err in c_check.items():
        print(f"C {key} agrees with ours to {err:.1e} (max relative difference of W)")
    print()
    verdicts = []
    for key in ("wlsm", "malsm"):
        rate = n / ours[key]
        verdicts.append((f"{key.upper()} >= 100x padasip", rate / padasip_rate >= 100))
        if key in c_rates:
            verdicts.append((f"{key.upper()} within 3x of C", rate / c_rates[key] >= 1 / 3))
    verdicts.append(("LSM(2000) under 1 ms", lsm_2000 < 1e-3))
    for text, ok in verdicts:
        print(f"target {text}: {'met' if ok else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
