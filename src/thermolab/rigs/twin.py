"""The digital twin: a simulated rig that evolves exactly in continuous time.

The twin is a linear heat-balance model around an ambient operating point,
with one state (the paper's box: lamp, fan, sensor voltage) or two (a TCLab
heater and its sensor), driven through a zero-order hold: the input applied at
one instant holds until the next ``apply``. Between input changes the state is
advanced by the exact matrix exponential over the elapsed clock time, so a
reading is exact at whatever instant it is taken; sampled every ``T`` seconds
with the ``paper`` preset it reproduces eq. 4 to rounding.

Model (deviation ``X`` of the states from the constant ambient ``y_amb``)::

    heater/box node:  τ dX1/dt = -(1 + c·f)(X1 - d(t)) + K·l
    sensor node:      τs dX2/dt = X1 - X2               (two-state models only)
    output:           y = y_amb + X_last

with ``l = max(u, 0)`` the lamp (heater) input, ``f = max(-u, 0)`` the fan
input, ``c`` the fan's cooling gain and ``d(t) = A sin(2π t / P + φ)`` the
ambient drift.

The fan: a fan blows room air over the box, so it can only carry heat away
faster; it cannot cool the box below the air it blows. It is therefore modelled
as a larger heat-loss rate (``1 + c·f``), not as a negative heat source: from
a warm state negative voltages cool the box faster (time constant
``τ / (1 + c·f)``), and at ambient they do nothing. Linearised around a warm
operating point this is a separate, negative incremental gain for the fan,
which is how the paper's "different gains for heating and cooling" appear.

Realism (each switchable, all seeded): Gaussian sensor noise, quantisation of
the reading (the 16-bit ±10 V board of the paper, or a TCLab's 10-bit ADC),
sample-time jitter (the instant actually sampled differs from the requested one
by a random, undisclosed amount), slow sinusoidal ambient drift (which the box
follows through its own dynamics), actuator saturation, and late samples.
An optional pure transport delay (``dead_time``) holds each input back
exactly, and a reading or input asked for a sample instant (``at=``) is
evaluated there, so a twin's record does not depend on how promptly it is
called.

The parameters and presets live in :mod:`thermolab.rigs.twin_params`, the
exact physics in :mod:`thermolab.rigs._thermal`; both are re-exported here.
"""

from __future__ import annotations

import collections
import math
from typing import Any

import numpy as np

from thermolab.errors import (
    InvalidParameterError,
    RigFaultError,
    RigStateError,
    RigTimeoutError,
)
from thermolab.rigs._thermal import ThermalModel
from thermolab.rigs.base import BaseRig
from thermolab.rigs.clock import Clock, RealClock
from thermolab.rigs.contract import Reading, RigState
from thermolab.rigs.twin_params import (
    DAQ16_STEP,
    PRESETS,
    TCLAB_STEP,
    TWIN_FAN,
    TwinParams,
    twin_info,
    twin_params,
    twin_preset,
)

__all__ = [
    "DAQ16_STEP",
    "PRESETS",
    "TCLAB_STEP",
    "TWIN_FAN",
    "TwinParams",
    "TwinRig",
    "twin_info",
    "twin_params",
    "twin_preset",
]


class _NormalStream:
    """Standard normal draws from a seeded generator, fetched in blocks for speed."""

    _BLOCK = 4096

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buffer: list[float] = []

    def __call__(self) -> float:
        if not self._buffer:
            self._buffer = self._rng.standard_normal(self._BLOCK).tolist()
            self._buffer.reverse()
        return self._buffer.pop()


class TwinRig(BaseRig):
    """A digital twin of a thermal rig (the default rig of the lab).

    Parameters
    ----------
    params : TwinParams or str, optional
        The parameters, or a preset name (``"paper"`` by default; see
        :data:`PRESETS`).
    clock : Clock, optional
        The clock that drives the physics and timestamps readings (default:
        :class:`~thermolab.rigs.clock.RealClock`; use a
        :class:`~thermolab.rigs.clock.VirtualClock` to run as fast as possible).
    seed : int, optional
        Seed of the realism (noise, jitter, drift phase). Two twins with the same
        parameters, seed and sequence of calls at the same clock instants give
        identical readings. ``None``: fresh entropy.
    realism : bool, optional
        ``False`` switches off noise, quantisation, jitter, drift and saturation
        of the chosen parameters (default ``True``: as the preset says).
    **overrides
        Any :class:`TwinParams` field, replacing the preset's value
        (``noise_std=0.01``, ``ambient=3.0``...).

    Raises
    ------
    InvalidParameterError
        For an unknown preset, an unknown override or an invalid value.

    Notes
    -----
    The twin starts at equilibrium (or at ``initial_output``) at the clock's
    time of construction, with the actuator at its safe input. Each noise source
    draws from its own stream of one seed, so switching one source off does not
    change the others' draws.

    Examples
    --------
    >>> from thermolab.rigs.clock import VirtualClock
    >>> clock = VirtualClock()
    >>> with TwinRig("paper", clock=clock) as rig:
    ...     rig.power_on()
    ...     rig.apply(10.0)
    ...     clock.sleep_until(250.126233)  # one time constant
    ...     round(rig.read().value, 6)      # 63.2 % of 10 V × 0.140090
    10.0
    0.885538
    """

    def __init__(
        self,
        params: TwinParams | str = "paper",
        *,
        clock: Clock | None = None,
        seed: int | None = None,
        realism: bool = True,
        **overrides: Any,
    ) -> None:
        base = twin_params(params, realism=realism, **overrides)
        self.params = base
        clock = clock if clock is not None else RealClock()
        super().__init__(twin_info(base), clock)
        # Children by index: a source added at the end leaves the earlier streams alone.
        noise_seq, jitter_seq, drift_seq, colored_seq, late_seq = np.random.SeedSequence(
            seed
        ).spawn(5)
        self._late_rng = np.random.default_rng(late_seq)
        self._late_sample: tuple[float, float] = (math.nan, 0.0)  # (instant asked, lateness)
        self._noise = _NormalStream(np.random.default_rng(noise_seq))
        self._colored = _NormalStream(np.random.default_rng(colored_seq))
        # The colored noise starts in its stationary distribution.
        self._colored_value = base.colored_noise_std * self._colored()
        self._colored_t = clock.now()
        self._jitter = _NormalStream(np.random.default_rng(jitter_seq))
        drift_phase = float(np.random.default_rng(drift_seq).uniform(0.0, 2.0 * math.pi))
        self._model = ThermalModel(base, drift_phase)
        self._model.start(clock.now())
        self._commanded = base.safe_input
        # Inputs on their way through the dead time: (instant they act, value), in order.
        self._in_transit: collections.deque[tuple[float, float]] = collections.deque()
        self._pending_fault: tuple[float, str, type[RigFaultError]] | None = None

    # -- fault injection (tests of the runner and the server) -------------------

    def inject_fault(
        self, reason: str = "injected fault", *, at: float | None = None, timeout: bool = False
    ) -> None:
        """Make the twin fault, now or at a clock instant.

        The first ``read`` or ``apply`` at or after ``at`` raises
        :class:`~thermolab.errors.RigFaultError` (or
        :class:`~thermolab.errors.RigTimeoutError` with ``timeout=True``)
        carrying ``reason``; the fault latches as on a real device and
        ``clear_fault()`` then succeeds (the injected cause is one-shot).

        Parameters
        ----------
        reason : str
            The fault message.
        at : float, optional
            Clock time of the fault; ``None``: the next call.
        timeout : bool
            Raise the timeout flavour of the error.
        """
        kind: type[RigFaultError] = RigTimeoutError if timeout else RigFaultError
        self._pending_fault = (self.clock.now() if at is None else float(at), reason, kind)

    def _raise_pending_fault(self, t: float) -> None:
        pending = self._pending_fault
        if pending is not None and t >= pending[0]:
            self._pending_fault = None
            raise pending[2](f"{self.describe().name}: {pending[1]}")

    # -- hooks --------------------------------------------------------------------

    def _drive(self, t: float, u: float) -> None:
        """Command input ``u`` at instant ``t``; it reaches the heat balance a dead time later."""
        self._commanded = u
        delay = self.params.dead_time
        if not delay:
            self._model.set_input(t, u)
            return
        arrival = t + delay
        if self._in_transit and arrival < self._in_transit[-1][0]:
            arrival = self._in_transit[-1][0]  # instants never go back
        self._in_transit.append((arrival, u))

    def _output_at(self, t: float) -> float:
        """Noise-free output at ``t``, once every input that has arrived by then acts."""
        in_transit = self._in_transit
        while in_transit and in_transit[0][0] <= t:
            arrival, u = in_transit.popleft()
            self._model.set_input(arrival, u)
        return self._model.output_at(t)

    def _sample_instant(self, *, reading: bool) -> float:
        """The instant a read or apply acts at: as asked, or late if the preset says so.

        A late sample is late for its reading and for the input that follows
        it (the same instant asked for), as when a host wakes late.
        """
        t = self._instant()
        p = self.params
        if not p.late_probability:
            return t
        asked, late = self._late_sample
        if reading or asked != t:
            draw = self._late_rng.random(2)
            late = -p.late_mean * math.log1p(-draw[1]) if draw[0] < p.late_probability else 0.0
            self._late_sample = (t, late)
        return t + late

    def _apply_input(self, u: float) -> float:
        t = self._sample_instant(reading=False)
        self._raise_pending_fault(t)
        sat = self.params.saturation
        if sat is not None:
            u = min(max(u, sat[0]), sat[1])
        self._drive(t, u)
        return u

    def _read_output(self) -> Reading:
        t = self._sample_instant(reading=True)
        self._raise_pending_fault(t)
        p = self.params
        instant = t + p.jitter_std * self._jitter() if p.jitter_std else t
        y = self._output_at(instant)
        if p.noise_std:
            y += p.noise_std * self._noise()
        if p.colored_noise_std:
            y += self._colored_noise_at(instant)
        if p.adc_range is not None:
            y = min(max(y, p.adc_range[0]), p.adc_range[1])
        if p.quant_step is not None:
            y = p.quant_origin + round((y - p.quant_origin) / p.quant_step) * p.quant_step
        return Reading(y, t)

    def _colored_noise_at(self, t: float) -> float:
        # Exact Ornstein-Uhlenbeck transition over the time since the last reading.
        elapsed = t - self._colored_t
        if elapsed > 0.0:
            p = self.params
            rho = math.exp(-elapsed / p.colored_noise_time)
            self._colored_value = (
                rho * self._colored_value
                + p.colored_noise_std * math.sqrt(1.0 - rho * rho) * self._colored()
            )
            self._colored_t = t
        return self._colored_value

    def _make_safe(self) -> None:
        # Every actuator to its declared default: the input, and the fan (a fan left
        # running would change the next run's plant: issue #23).
        t = self._instant()
        self._drive(t, self.params.safe_input)
        self._output_at(t)  # inputs in transit up to t act before the fan changes
        self._model.set_fan(t, TWIN_FAN.default / 100.0)

    def _release(self) -> None:
        pass

    def _check_fault_cleared(self) -> None:
        # The injected cause is gone once raised; an over-limit output must have fallen.
        now = self.clock.now()
        self._check_limit(Reading(self._output_at(now), now))

    # -- the disturbance fan --------------------------------------------------------

    def _set_further_input(self, name: str, value: float) -> float:
        t = self._instant()
        self._output_at(t)  # inputs in transit up to t act first
        self._model.set_fan(t, value / 100.0)
        return value

    def _further_level(self, name: str) -> float:
        return self.fan

    def set_fan(self, percent: float, *, at: float | None = None) -> float:
        """Run the disturbance fan at ``percent`` (0-100) of full speed from ``at`` on.

        The fan blows room air over the box: the heat-loss rate is multiplied
        by ``1 + disturbance_fan_gain · percent / 100`` (see
        :class:`TwinParams`); it acts at once (no transport delay). Returns
        the level set. Allowed in any state; a closed rig refuses it.

        Raises
        ------
        InvalidParameterError
            If ``percent`` is not a number in [0, 100].
        """
        try:
            level = float(percent)
        except (TypeError, ValueError):
            raise InvalidParameterError(f"the fan takes 0-100 %, got {percent!r}") from None
        if not (math.isfinite(level) and 0.0 <= level <= 100.0):
            raise InvalidParameterError(f"the fan takes 0-100 %, got {percent!r}")
        with self._lock:
            if self.state is RigState.CLOSED:
                raise RigStateError("the rig is closed")
            t = self.clock.now() if at is None else at
            self._output_at(t)  # inputs in transit up to t act first
            self._model.set_fan(t, level / 100.0)
        return level

    @property
    def fan(self) -> float:
        """The disturbance fan's level, % of full speed."""
        return 100.0 * self._model.fan

    # -- twin-only inspection ------------------------------------------------------

    @property
    def applied_input(self) -> float:
        """The input the actuator holds now (the safe value unless powered).

        With a dead time this is the last input commanded; the heat balance
        feels it ``dead_time`` seconds later.
        """
        return self._commanded

    def true_output(self, t: float | None = None) -> float:
        """Noise-free output at clock time ``t`` (default: now), for tests and plots.

        Parameters
        ----------
        t : float, optional
            Clock time, not before the last input change (nor, with a dead
            time, before an earlier call's ``t``).

        Returns
        -------
        float
        """
        return self._output_at(self.clock.now() if t is None else t)
