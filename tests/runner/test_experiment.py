"""The sampling loop: schedule, lateness, inputs, END, events, subscribers, records."""

from __future__ import annotations

import csv
import math
import threading
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from thermolab.errors import InvalidParameterError, RunStateError
from thermolab.rigs import RealClock, VirtualClock
from thermolab.runner import (
    CsvRecorder,
    EndReason,
    EstimateEvent,
    Event,
    EventBus,
    Experiment,
    RunState,
    SampleEvent,
    StateEvent,
)
from thermolab.signals import parse_signal

from .conftest import FakeEstimate, HookedTwin, MeanIdentifier


class OversleepingClock:
    """Virtual time whose every sleep overshoots by a random 0-30 % of ``dt``.

    A loop that slept ``dt`` after each sample would drift by the accumulated
    overshoot; a drift-free schedule does not.
    """

    def __init__(self, dt: float, seed: int) -> None:
        self._clock = VirtualClock()
        self._rng = np.random.default_rng(seed)
        self._dt = dt

    def now(self) -> float:
        return self._clock.now()

    def sleep_until(self, t: float) -> None:
        self._clock.sleep_until(t + self._rng.uniform(0.0, 0.3) * self._dt)


def test_schedule_is_drift_free_over_a_long_run_with_oversleeping() -> None:
    dt, n = 1.0, 50_000
    clock = OversleepingClock(dt, seed=3)
    with HookedTwin("paper", clock=clock) as rig:  # type: ignore[arg-type]
        result = Experiment(rig, dt, n, set_point=5.0, interlocks=None).run()
    assert result.samples == n
    assert_array_equal(result.t, np.arange(n) * dt)
    # Every sample lands within one overshoot of its own deadline, at the end as
    # at the start: the error does not accumulate (it would reach ~7500 s here).
    assert result.lateness.min() >= 0.0
    assert result.lateness.max() <= 0.3 * dt
    assert 0.0 <= result.jitter[-1] <= 0.3 * dt
    # The same lateness at the end as at the start.
    assert_allclose(result.lateness[-5000:].mean(), result.lateness[:5000].mean(), atol=0.01 * dt)
    assert result.late > 0
    assert result.missed == 0


def test_schedule_keeps_k_dt_exactly_with_an_inexact_period_and_a_far_origin() -> None:
    dt, n = 0.1, 100_000
    clock = VirtualClock(start=1.0e6)
    with HookedTwin("paper", clock=clock) as rig:
        result = Experiment(rig, dt, n, set_point=1.0).run()
    assert result.samples == n
    assert_array_equal(result.t, np.arange(n) * dt)
    assert np.abs(result.jitter).max() < 1e-6
    assert result.late == 0
    assert_allclose(clock.now(), 1.0e6 + (n - 1) * dt, rtol=0, atol=1e-6)


def test_a_stall_makes_late_samples_that_are_recorded_not_skipped(
    twin: HookedTwin, clock: VirtualClock
) -> None:
    twin.hooks[10] = lambda: clock.advance(2.5)  # the 11th reading takes 2.5 s
    result = Experiment(twin, 1.0, 20, set_point=5.0).run()
    assert result.samples == 20
    assert_array_equal(result.t, np.arange(20.0))
    assert result.jitter[10] == 0.0  # a twin samples at the scheduled instant, however slow
    assert result.lateness[10] == 0.0
    assert result.lateness[11] == pytest.approx(1.5)
    assert result.lateness[12] == pytest.approx(0.5)
    assert (result.lateness[13:] == 0.0).all()
    assert result.late == 2
    assert result.missed == 1  # while sample 11 was overdue, the deadline of 12 passed


def test_set_point_changes_mid_run_from_the_next_sample(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 100, set_point=2.0)
    twin.hooks[50] = lambda: exp.set_input(10.0)
    result = exp.run()
    assert (result.u[:50] == 2.0).all()
    assert (result.u[50:] == 10.0).all()
    assert exp.set_point == 10.0


def test_set_input_out_of_range_is_refused_and_changes_nothing(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 10, set_point=2.0)
    with pytest.raises(InvalidParameterError, match=r"outside the range of 'twin:paper'"):
        exp.set_input(11.0)
    with pytest.raises(InvalidParameterError, match="must be a number"):
        exp.set_input("hot")  # type: ignore[arg-type]
    assert (exp.run().u == 2.0).all()


def test_signal_drives_the_input_and_a_set_point_can_take_over(twin: HookedTwin) -> None:
    signal = parse_signal("square:4:6:0.1")
    exp = Experiment(twin, 1.0, 40, signal=signal)
    twin.hooks[30] = lambda: exp.set_input(0.0)
    result = exp.run()
    assert_array_equal(result.u[:30], signal.sample(np.arange(30.0)))
    assert (result.u[30:] == 0.0).all()
    assert exp.set_point == 0.0


def test_set_signal_switches_back_from_manual(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 20, set_point=1.0)
    twin.hooks[10] = lambda: exp.set_signal(parse_signal("const:3"))
    result = exp.run()
    assert (result.u[:10] == 1.0).all()
    assert (result.u[10:] == 3.0).all()
    assert exp.set_point is None


def test_end_stops_after_the_current_sample_and_finishes_identifiers(twin: HookedTwin) -> None:
    ident = MeanIdentifier()
    exp = Experiment(twin, 1.0, 2000, set_point=10.0, identifiers={"mean": ident})
    twin.hooks[100] = exp.end
    result = exp.run()
    assert result.end_reason is EndReason.ENDED
    assert result.state is RunState.FINISHED
    assert result.samples == 101
    assert ident.finished
    final = result.methods["mean"].final
    assert isinstance(final, FakeEstimate)
    assert final.n == 101
    assert final.mean == pytest.approx(float(result.y.mean()), rel=1e-12)
    assert twin.applied_input == 0.0


def test_end_before_start_is_an_illegal_transition(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 10)
    with pytest.raises(RunStateError, match="has not started"):
        exp.end()


def test_a_run_starts_only_once(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 5)
    exp.run()
    with pytest.raises(RunStateError, match="illegal transition finished -> running"):
        exp.run()
    with pytest.raises(RunStateError, match="cannot START"):
        exp.start()
    with pytest.raises(RunStateError, match="the run is finished"):
        exp.set_input(1.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dt": 0.0}, "dt must be a positive number"),
        ({"dt": math.inf}, "dt must be a positive number"),
        ({"samples": 0}, "samples must be an integer >= 1"),
        ({"samples": 10.5}, "samples must be an integer >= 1"),
        ({"set_point": 20.0}, "outside the range"),
        ({"set_point": 1.0, "signal": parse_signal("const:1")}, "not both"),
        ({"late_tolerance": -1.0}, "late_tolerance"),
        ({"identifiers": {"x": object()}}, "lacks update/finish/to_dict"),
    ],
)
def test_invalid_run_parameters(twin: HookedTwin, kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"dt": 1.0, "samples": 10, **kwargs}
    with pytest.raises(InvalidParameterError, match=match):
        Experiment(twin, **args)  # type: ignore[arg-type]


def test_events_come_in_order(twin: HookedTwin) -> None:
    n = 6
    exp = Experiment(twin, 1.0, n, set_point=10.0, identifiers={"mean": MeanIdentifier(every=2)})
    sub = exp.events.subscribe()
    exp.run()
    events = list(sub)
    assert [e.seq for e in events] == list(range(len(events)))
    summary: list[tuple[str, object]] = []
    for e in events:
        if isinstance(e, StateEvent):
            summary.append(("state", e.state))
        elif isinstance(e, SampleEvent):
            summary.append(("sample", e.k))
        elif isinstance(e, EstimateEvent):
            summary.append(("estimate", (e.k, e.final)))
    expected: list[tuple[str, object]] = [("state", RunState.RUNNING)]
    for k in range(n):
        expected.append(("sample", k))
        if (k + 1) % 2 == 0:
            expected.append(("estimate", (k, False)))
    expected += [
        ("state", RunState.ENDING),
        ("estimate", (n - 1, True)),
        ("state", RunState.FINISHED),
    ]
    assert summary == expected
    last = events[-1]
    assert isinstance(last, StateEvent)
    assert last.reason == "completed"


def test_a_blocked_subscriber_does_not_delay_sampling(twin: HookedTwin) -> None:
    release = threading.Event()

    def stuck(event: Event) -> None:
        release.wait(30.0)

    exp = Experiment(twin, 1.0, 20_000, set_point=10.0, identifiers={"mean": MeanIdentifier()})
    blocked = exp.events.subscribe_callback(stuck, maxsize=100, name="stuck")
    everything = exp.events.subscribe(maxsize=100_000)
    try:
        # Completes while the subscriber is still blocked: publishing never waited for it.
        result = exp.run()
    finally:
        release.set()
    assert result.end_reason is EndReason.COMPLETED
    assert result.samples == 20_000
    assert blocked.cut
    events = everything.drain()
    samples = [e for e in events if isinstance(e, SampleEvent)]
    assert len(samples) == 20_000
    last = events[-1]
    assert isinstance(last, StateEvent)
    assert last.state is RunState.FINISHED


def test_csv_rows_are_on_disk_while_the_run_goes_on(twin: HookedTwin, tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    seen: list[list[dict[str, str]]] = []

    def read_csv() -> None:
        with path.open(newline="") as f:
            seen.append(list(csv.DictReader(f)))

    twin.hooks[500] = read_csv
    result = Experiment(twin, 1.0, 1000, set_point=10.0, recorder=CsvRecorder(path)).run()
    (mid_run,) = seen
    assert len(mid_run) == 500  # samples 0..499, flushed as each was taken
    assert mid_run[-1]["k"] == "499"
    assert float(mid_run[-1]["y"]) == result.y[499]
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert_array_equal([float(r["y"]) for r in rows], result.y)
    assert_array_equal([float(r["u"]) for r in rows], result.u)
    assert_array_equal([float(r["t"]) for r in rows], result.t)


def test_snapshot_while_running_and_the_result_after(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 50, set_point=10.0)
    snaps = []
    twin.hooks[20] = lambda: snaps.append(exp.snapshot())
    result = exp.run()
    (snap,) = snaps
    assert snap.state is RunState.RUNNING
    assert snap.samples == 20
    assert_array_equal(snap.y, result.y[:20])
    assert exp.snapshot() is result


def test_worker_thread_run_with_live_set_point_and_end() -> None:
    # Real time, 10 ms period: the set point and END come from another thread.
    with HookedTwin("paper", clock=RealClock()) as rig:
        exp = Experiment(rig, 0.01, 5000, set_point=1.0, late_tolerance=0.01)
        sub = exp.events.subscribe(maxsize=100_000)
        exp.start()
        # This thread may read the events late (a busy machine): END only once a sample
        # shows the new set point, which a CI run's END had overtaken.
        for event in sub:
            if isinstance(event, SampleEvent) and event.k == 20:
                exp.set_input(7.0)
            if isinstance(event, SampleEvent) and event.k > 20 and event.u == 7.0:
                exp.end()
                break
        result = exp.wait(10.0)
        assert result is not None
        assert result.end_reason is EndReason.ENDED
        assert 22 <= result.samples < 5000
        changes = np.flatnonzero(np.diff(result.u))
        assert len(changes) == 1
        assert changes[0] >= 20
        assert result.u[-1] == 7.0
        assert rig.applied_input == 0.0
        assert not rig.powered


def test_identifiers_see_the_applied_input_and_the_reading(twin: HookedTwin) -> None:
    seen: list[tuple[float, float]] = []

    class Spy(MeanIdentifier):
        def update(self, u: float, y: float) -> FakeEstimate | None:
            seen.append((u, y))
            return super().update(u, y)

    result = Experiment(
        twin, 1.0, 30, signal=parse_signal("step:0:10@5"), identifiers={"spy": Spy()}
    ).run()
    assert_array_equal(np.array(seen), np.column_stack([result.u, result.y]))
    trajectory = result.methods["spy"]
    assert_array_equal(trajectory.k, range(30))
    assert trajectory.to_dict()["estimates"] == 30
    assert trajectory.last == FakeEstimate(30, float(result.y.mean()))
    assert trajectory.final == FakeEstimate(30, float(result.y.mean()))
    # An estimate without K / tau leaves NaN in the arrays, never an error.
    assert np.isnan(trajectory.K).all()
    assert not trajectory.valid.any()


def test_result_to_dict_is_json_ready(twin: HookedTwin) -> None:
    import json

    result = Experiment(twin, 1.0, 5, set_point=1.0, identifiers={"m": MeanIdentifier()}).run()
    data = json.loads(json.dumps(result.to_dict(samples=True, trajectories=True)))
    assert data["end_reason"] == "completed"
    assert data["samples"] == 5
    assert data["methods"]["m"]["latest"] == {"n": 5, "mean": pytest.approx(result.y.mean())}
    assert len(data["y"]) == 5
    assert data["methods"]["m"]["trajectory"]["k"] == [0, 1, 2, 3, 4]


def test_an_event_bus_can_be_shared(twin: HookedTwin) -> None:
    bus = EventBus()
    sub = bus.subscribe()
    Experiment(twin, 1.0, 3, events=bus).run()
    assert bus.closed
    assert len(list(sub)) == 1 + 3 + 2


@pytest.mark.parametrize("spec", ["prbs:2:8:0.7:3", "sine:5:4:0.013", "square:4:6:0.1"])
def test_signal_values_are_exactly_value_at_k_dt_across_blocks(spec: str) -> None:
    # The loop evaluates signals a block of samples at a time; the values must be
    # those of value(k * dt), across block boundaries and after a mid-run switch.
    dt, n = 0.1, 9000
    first, second = parse_signal(spec), parse_signal("step:1:9@700")
    with HookedTwin("paper", clock=VirtualClock()) as rig:
        exp = Experiment(rig, dt, n, signal=first)
        rig.hooks[5000] = lambda: exp.set_signal(second)
        result = exp.run()
    expected = [first.value(k * dt) for k in range(5000)]
    expected += [second.value(k * dt) for k in range(5000, n)]
    assert result.u.tolist() == expected
