"""Closed-loop set-point steps on the twins: measured vs predicted, for each tuning rule.

For each twin (``sim:tclab``, the kit's physics; ``sim``, the paper's model)
and each rule of :mod:`thermolab.control.tuning`, the PID tuned from the
twin's FOPDT figures runs a set-point step on the twin (virtual clock, seeded)
and the same step is predicted from the model with the same PID. The peer of
each measured figure is that prediction, made in the same run. Also prints the
runner's cost of the PID per sample (a 20 000-sample run with and without it).

    .venv/bin/python benchmarks/bench_control.py
    .venv/bin/python benchmarks/bench_control.py --samples 2000 --speed-samples 50000
"""

from __future__ import annotations

import argparse
import math
import time

from thermolab.control import FOPDT, predict_closed_loop, step_metrics, tune
from thermolab.rigs import VirtualClock
from thermolab.rigs.twin import TwinRig
from thermolab.runner import ControlLoop, Experiment
from thermolab.signals import parse_signal

# (rig preset, FOPDT figures, operating point y0, set point after the step, tau_c).
# The kit's figures are the twin's documented FOPDT fit (tau_c = theta, SIMC's tight
# tuning); the paper's twin is a pure first-order lag, given half a sample of dead
# time (the zero-order hold's) so that the rules that need theta > 0 (zn, cc) apply,
# and tau_c = 100 s so that imc and simc do not simply saturate the ±10 V heater.
CASES = {
    "sim:tclab": ("tclab", FOPDT(0.6, 140.0, 15.9), 21.0, 50.0, None),
    "sim": ("paper", FOPDT(0.140090, 250.126233, 0.5), 0.0, 0.5, 100.0),
}
RULES = (("imc", "pid"), ("imc", "pi"), ("simc", "pi"), ("zn", "pid"), ("zn", "pi"),
         ("cc", "pid"), ("cc", "pi"))  # fmt: skip
STEP_AT = 60.0


def _fmt(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def closed_loop_table(samples: int, seed: int) -> None:
    print(
        f"{'rig':<10} {'rule':<9} {'Kp':>9} {'Ti (s)':>8} {'Td (s)':>7} | "
        f"{'overshoot %':>11} {'(model)':>8} | {'settling s':>10} {'(model)':>8} | "
        f"{'IAE':>8} {'(model)':>8}"
    )
    print("-" * 112)
    for name, (preset, model, y0, r1, tau_c) in CASES.items():
        for rule, form in RULES:
            speed = tau_c if rule in ("imc", "simc") else None
            tuning = tune(model, rule, form=form, tau_c=speed)
            profile = parse_signal(f"step:{y0:g}:{r1:g}@{STEP_AT:g}", limits=(-1e9, 1e9))
            with TwinRig(preset, clock=VirtualClock(), seed=seed) as rig:
                info = rig.describe()
                loop = ControlLoop(tuning.gains, profile)
                result = Experiment(rig, 1.0, samples, controller=loop).run()
            measured = step_metrics(result.t, result.extra["r"], result.y)
            predicted = predict_closed_loop(
                model, tuning.gains, dt=1.0, samples=samples, setpoint=r1, step_at=STEP_AT,
                y0=y0, u0=info.safe_input, u_limits=info.input_range,
            ).metrics  # fmt: skip
            g = tuning.gains
            print(
                f"{name:<10} {rule + ' ' + form:<9} {g.Kp:>9.4g} {g.Ti:>8.4g} {g.Td:>7.3g} | "
                f"{_fmt(measured.overshoot):>11} {_fmt(predicted.overshoot):>8} | "
                f"{_fmt(measured.settling_time, 0):>10} {_fmt(predicted.settling_time, 0):>8} | "
                f"{measured.iae:>8.4g} {predicted.iae:>8.4g}"
            )


def runner_cost(samples: int, repeat: int) -> None:
    gains = tune(CASES["sim"][1], "simc").gains

    def once(with_pid: bool) -> float:
        with TwinRig("paper", clock=VirtualClock(), realism=False) as rig:
            if with_pid:
                exp = Experiment(rig, 1.0, samples, controller=ControlLoop(gains, 1.0))
            else:
                exp = Experiment(rig, 1.0, samples, set_point=7.0)
            start = time.perf_counter()
            exp.run()
            return time.perf_counter() - start

    best = {False: math.inf, True: math.inf}
    for _ in range(repeat):
        for with_pid in (False, True):
            best[with_pid] = min(best[with_pid], once(with_pid))
    open_us = best[False] / samples * 1e6
    pid_us = best[True] / samples * 1e6
    print(
        f"\nrunner, {samples} samples on the paper twin (best of {repeat}): "
        f"open loop {open_us:.2f} µs/sample, PID {pid_us:.2f} µs/sample "
        f"(the PID and its channels, fan included: +{pid_us - open_us:.2f} µs/sample)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1500, help="samples per closed-loop run")
    parser.add_argument("--seed", type=int, default=1, help="seed of the twins' noise")
    parser.add_argument("--speed-samples", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    closed_loop_table(args.samples, args.seed)
    runner_cost(args.speed_samples, args.repeat)


if __name__ == "__main__":
    main()
