"""What a run produced: each method's estimates (MethodResult) and the run (RunResult).

Kept apart from the sampling loop (:mod:`thermolab.runner.experiment`), which
fills a :class:`MethodTrack` per identifier and builds the results from them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.jsonsafe import json_safe
from thermolab.records import RUN_CHANNELS, ChannelSpec
from thermolab.rigs import RigInfo
from thermolab.runner.events import SupportsToDict
from thermolab.runner.state import EndReason, RunState

__all__ = ["MethodResult", "MethodTrack", "RunResult"]

_FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class MethodResult:
    """What one identifier produced during a run.

    The estimates ``update`` returned are kept as arrays (``k``, ``K``, ``tau``,
    ``valid``), not as objects: a 20,000-sample run of a recursive method makes
    20,000 estimates, and keeping them alive would cost the sampling loop
    garbage-collector time. The identifier itself keeps its full parameter
    trajectory (``OnlineIdentifier.trajectory()``, with ``W``).

    Attributes
    ----------
    name : str
        The identifier's name in the run.
    k : numpy.ndarray
        Sample index of each estimate ``update`` returned (int64; empty for
        SRM and LSM, whose result appears only at END).
    K, tau : numpy.ndarray
        Gain and time constant of each of those estimates (NaN where an
        estimate has none, or has no ``K`` / ``tau`` attribute).
    valid : numpy.ndarray
        Whether each of those estimates has a first-order meaning (bool).
    last : object or None
        The last estimate ``update`` returned, or ``None``.
    final : object or None
        The estimate ``finish`` returned at END (for SRM and LSM the result;
        for the others the last estimate, marked final), or ``None`` (the run
        was aborted or failed, or the method had no estimate).
    error : str or None
        Why the method stopped early (not enough excitation...), or ``None``.
    """

    name: str
    k: npt.NDArray[np.int64]
    K: _FloatArray
    tau: _FloatArray
    valid: npt.NDArray[np.bool_]
    last: SupportsToDict | None
    final: SupportsToDict | None
    error: str | None = None

    @property
    def latest(self) -> SupportsToDict | None:
        """The final estimate, else the last one produced, else ``None``."""
        return self.final if self.final is not None else self.last

    def to_dict(self, *, trajectory: bool = False) -> dict[str, Any]:
        """Return a JSON-ready dictionary.

        Parameters
        ----------
        trajectory : bool, optional
            Include the arrays ``k``, ``K``, ``tau``, ``valid`` as lists (NaN as
            ``None``); default: only the count and the latest estimate.

        Returns
        -------
        dict
        """
        latest = self.latest
        out: dict[str, Any] = {
            "name": self.name,
            "estimates": len(self.k),
            "latest": None if latest is None else latest.to_dict(),
            "final": self.final is not None,
            "error": self.error,
        }
        if trajectory:
            out["trajectory"] = {
                "k": self.k.tolist(),
                "K": json_safe(self.K),
                "tau": json_safe(self.tau),
                "valid": self.valid.tolist(),
            }
        return out


class MethodTrack:
    """The estimates of one method during a run, as plain lists (see MethodResult)."""

    __slots__ = ("K", "k", "last", "tau", "valid")

    def __init__(self) -> None:
        self.k: list[int] = []
        self.K: list[float] = []
        self.tau: list[float] = []
        self.valid: list[bool] = []
        self.last: SupportsToDict | None = None

    def add(self, k: int, estimate: SupportsToDict) -> None:
        self.k.append(k)
        self.K.append(getattr(estimate, "K", math.nan))
        self.tau.append(getattr(estimate, "tau", math.nan))
        self.valid.append(bool(getattr(estimate, "valid", False)))
        self.last = estimate

    def result(self, name: str, final: SupportsToDict | None, error: str | None) -> MethodResult:
        # A snapshot from another thread may catch add() halfway: cut to the shortest list.
        n = min(len(self.k), len(self.K), len(self.tau), len(self.valid))
        return MethodResult(
            name=name,
            k=np.array(self.k[:n], dtype=np.int64),
            K=np.array(self.K[:n], dtype=np.float64),
            tau=np.array(self.tau[:n], dtype=np.float64),
            valid=np.array(self.valid[:n], dtype=np.bool_),
            last=self.last,
            final=final,
            error=error,
        )


@dataclass(frozen=True, eq=False)
class RunResult:
    """Everything a run recorded.

    Attributes
    ----------
    rig : RigInfo
        The rig that was sampled.
    dt : float
        Sample period in seconds.
    samples_requested : int
        The number of samples asked for.
    t, u, y : numpy.ndarray
        Scheduled time ``k·dt``, applied input and read output of each sample taken.
    t_read : numpy.ndarray
        When each reading was taken, seconds after START.
    jitter : numpy.ndarray
        ``t_read - t``.
    lateness : numpy.ndarray
        How long after its deadline the loop woke for each sample (>= 0).
    busy : numpy.ndarray
        Wall-clock seconds the loop spent on each sample (rig I/O, checks,
        recording, events, identifiers): the runner's real-time budget.
    state : RunState
        FINISHED, FAULTED or ABORTED.
    end_reason : EndReason
        Why the run ended.
    message : str
        One line about the end (empty for a normal completion).
    late : int
        Samples whose lateness exceeded the tolerance.
    missed : int
        Deadlines that passed while a sample was overdue (``sum(lateness // dt)``).
    late_tolerance : float
        The lateness (seconds) above which a sample counts as late.
    methods : dict of str to MethodResult
        Each identifier's results, by name.
    signum : int or None
        The number of the signal that interrupted the run (SIGINT, SIGTERM),
        else ``None``.
    error : BaseException or None
        The exception that ended the run (rig fault, error), else ``None``.
    extra : dict of str to numpy.ndarray
        The run's extra channels (``Experiment(sources=...)``), by name.
    channels : tuple of ChannelSpec
        Every channel of the record, in column order (``t, u, y, k, t_read,
        jitter, lateness``, then the extra ones).
    control : dict or None
        The control loop at the end (:meth:`ControlLoop.to_dict`: mode, set
        point, gains), or ``None`` for an open-loop run.
    """

    rig: RigInfo
    dt: float
    samples_requested: int
    t: _FloatArray
    u: _FloatArray
    y: _FloatArray
    t_read: _FloatArray
    jitter: _FloatArray
    lateness: _FloatArray
    busy: _FloatArray
    state: RunState
    end_reason: EndReason
    message: str
    late: int
    missed: int
    late_tolerance: float
    methods: dict[str, MethodResult] = field(default_factory=dict)
    signum: int | None = None
    error: BaseException | None = None
    extra: dict[str, _FloatArray] = field(default_factory=dict)
    channels: tuple[ChannelSpec, ...] = RUN_CHANNELS
    control: dict[str, Any] | None = None

    @property
    def samples(self) -> int:
        """The number of samples taken."""
        return len(self.t)

    @property
    def ok(self) -> bool:
        """``True`` if the run FINISHED (completed or ended by END)."""
        return self.state is RunState.FINISHED

    def to_dict(self, *, samples: bool = False, trajectories: bool = False) -> dict[str, Any]:
        """Return a JSON-ready dictionary.

        Parameters
        ----------
        samples : bool, optional
            Include the sample arrays as lists (default ``False``).
        trajectories : bool, optional
            Include every estimate of every method (default ``False``).

        Returns
        -------
        dict
        """
        out: dict[str, Any] = {
            "rig": self.rig.to_dict(),
            "dt": self.dt,
            "samples_requested": self.samples_requested,
            "samples": self.samples,
            "state": self.state.value,
            "end_reason": self.end_reason.value,
            "message": self.message,
            "late": self.late,
            "missed": self.missed,
            "late_tolerance": self.late_tolerance,
            "max_lateness": float(self.lateness.max()) if self.samples else 0.0,
            "signum": self.signum,
            "methods": {
                name: m.to_dict(trajectory=trajectories) for name, m in self.methods.items()
            },
        }
        if samples:
            for key in ("t", "u", "y", "t_read", "jitter", "lateness"):
                out[key] = getattr(self, key).tolist()
            out["extra"] = {name: json_safe(v) for name, v in self.extra.items()}
        out["channels"] = [c.to_dict() for c in self.channels]
        if self.control is not None:
            out["control"] = self.control
        return out
