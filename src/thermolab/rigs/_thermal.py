"""The twin's physics: exact continuous-time evolution of a linear heat balance."""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from thermolab.rigs.twin_params import TwinParams


@dataclass(frozen=True, slots=True)
class _Modes:
    """Modal form of the state matrix for one fan level (cached).

    Plain tuples, not arrays: with one or two states, Python floats are several
    times faster than NumPy's per-call overhead, and the twin is evaluated at
    every sample of an as-fast-as-possible run.
    """

    eigenvalues: tuple[float, ...]
    vectors: tuple[tuple[float, ...], ...]  # vectors[j][i]: state j of mode i
    vectors_inv: tuple[tuple[float, ...], ...]
    steady_per_lamp: tuple[float, ...]  # steady state per unit of lamp input
    drift_response: tuple[complex, ...]  # state response phasor to unit drift


class ThermalModel:
    """Exact continuous-time evolution of the twin's linear heat balance."""

    def __init__(self, params: TwinParams, drift_phase: float) -> None:
        self._p = params
        self._n = 1 if params.sensor_lag is None else 2
        self._omega = 2.0 * math.pi / params.drift_period
        self._phase = drift_phase
        self._modes_cache: dict[float, _Modes] = {}
        start = params.initial_output if params.initial_output is not None else params.ambient
        self._anchor_t = 0.0
        self._anchor_state: tuple[float, ...] = (start - params.ambient,) * self._n
        self._input = params.safe_input
        self._fan = 0.0  # the disturbance fan's level, 0..1
        self._set_segment()

    def _modes(self, fan: float) -> _Modes:
        # ``fan`` is the whole extra heat-loss factor: the input's fan and the disturbance's.
        cached = self._modes_cache.get(fan)
        if cached is not None:
            return cached
        p = self._p
        loss = (1.0 + fan) / p.time_constant
        if self._n == 1:
            M = np.array([[-loss]])
            b = np.array([p.gain / p.time_constant])
            e = np.array([loss])
        else:
            assert p.sensor_lag is not None
            M = np.array([[-loss, 0.0], [1.0 / p.sensor_lag, -1.0 / p.sensor_lag]])
            b = np.array([p.gain / p.time_constant, 0.0])
            e = np.array([loss, 0.0])
        eigenvalues, vectors = np.linalg.eig(M)
        # A heat balance with distinct lags has real, distinct, negative eigenvalues.
        vectors = vectors.real
        drift = np.linalg.solve(1j * self._omega * np.eye(self._n) - M, e.astype(complex))
        modes = _Modes(
            eigenvalues=tuple(float(v) for v in eigenvalues.real),
            vectors=tuple(tuple(float(x) for x in row) for row in vectors),
            vectors_inv=tuple(tuple(float(x) for x in row) for row in np.linalg.inv(vectors)),
            steady_per_lamp=tuple(float(x) for x in -np.linalg.solve(M, b)),
            drift_response=tuple(complex(x) for x in drift),
        )
        if len(self._modes_cache) > 256:  # a sine input visits many fan levels
            self._modes_cache.clear()
        self._modes_cache[fan] = modes
        return modes

    def _drift_state(self, modes: _Modes, t: float) -> tuple[float, ...]:
        if self._p.drift_amplitude == 0.0:
            return (0.0,) * self._n
        phasor = self._p.drift_amplitude * cmath.exp(1j * (self._omega * t + self._phase))
        return tuple((r * phasor).imag for r in modes.drift_response)

    def _set_segment(self) -> None:
        """Precompute the scalar coefficients of the output for the current input."""
        u = self._input
        lamp, fan = max(u, 0.0), max(-u, 0.0)
        modes = self._modes(self._p.fan_gain * fan + self._p.disturbance_fan_gain * self._fan)
        self._seg_modes = modes
        self._seg_steady = tuple(s * lamp for s in modes.steady_per_lamp)
        drift = self._drift_state(modes, self._anchor_t)
        free = [
            x - s - d for x, s, d in zip(self._anchor_state, self._seg_steady, drift, strict=True)
        ]
        z = tuple(sum(r * f for r, f in zip(row, free, strict=True)) for row in modes.vectors_inv)
        self._seg_z = z
        self._seg_weights = tuple(v * zi for v, zi in zip(modes.vectors[-1], z, strict=True))
        self._seg_const = self._p.ambient + self._seg_steady[-1]
        drift_out = modes.drift_response[-1] * self._p.drift_amplitude
        self._seg_drift_amp = abs(drift_out)
        self._seg_drift_phase = self._phase + cmath.phase(drift_out)

    def state_at(self, t: float) -> tuple[float, ...]:
        """Deviation state at ``t`` (not before the last input change)."""
        modes = self._seg_modes
        dt = max(t - self._anchor_t, 0.0)
        decayed = [
            zi * math.exp(lam * dt) for lam, zi in zip(modes.eigenvalues, self._seg_z, strict=True)
        ]
        drift = self._drift_state(modes, t)
        return tuple(
            s + d + sum(v * c for v, c in zip(row, decayed, strict=True))
            for s, d, row in zip(self._seg_steady, drift, modes.vectors, strict=True)
        )

    def output_at(self, t: float) -> float:
        """Noise-free output at ``t``; instants before the last input change are clamped to it."""
        dt = t - self._anchor_t
        if dt < 0.0:
            t, dt = self._anchor_t, 0.0
        y = self._seg_const
        for lam, w in zip(self._seg_modes.eigenvalues, self._seg_weights, strict=True):
            y += w * math.exp(lam * dt)
        if self._seg_drift_amp:
            y += self._seg_drift_amp * math.sin(self._omega * t + self._seg_drift_phase)
        return y

    def start(self, t: float) -> None:
        """Put the model's clock origin at ``t`` (construction time)."""
        self._anchor_t = t
        self._set_segment()

    def set_input(self, t: float, u: float) -> None:
        """Hold input ``u`` from instant ``t`` on (zero-order hold)."""
        if u == self._input:
            return  # re-anchoring an unchanged input would only accumulate rounding
        t = max(t, self._anchor_t)
        self._anchor_state = self.state_at(t)
        self._anchor_t = t
        self._input = u
        self._set_segment()

    def set_fan(self, t: float, level: float) -> None:
        """Run the disturbance fan at ``level`` (0..1 of full speed) from instant ``t`` on."""
        if level == self._fan:
            return
        t = max(t, self._anchor_t)
        self._anchor_state = self.state_at(t)
        self._anchor_t = t
        self._fan = level
        self._set_segment()

    @property
    def fan(self) -> float:
        return self._fan

    @property
    def input(self) -> float:
        return self._input
