"""A script's turn at a rig (:class:`Turn`) and what it reads (:class:`Reading`).

:meth:`thermolab.client.Lab.control` hands out a :class:`Turn` once the
script's place in the queue comes up; the turn keeps itself alive and
extended from a thread of its own until it is released or the lab ends it.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING, Any

from thermolab.client.errors import LabRequestError, TurnEndedError
from thermolab.errors import InvalidParameterError

if TYPE_CHECKING:
    from thermolab.client.lab import Lab

__all__ = ["Reading", "Turn"]


@dataclass(frozen=True, slots=True)
class Reading:
    """A rig's output: ``y`` in ``unit`` at ``at``; ``u`` the input applied; ``fresh`` read now.

    ``channels``: the rig's further channels, read with ``y`` (a kit's ``t2``)
    or at their level (``q2``); empty for a rig that has none.
    """

    y: float | None
    at: datetime | None
    u: float | None
    unit: str
    fresh: bool
    channels: dict[str, float | None] = field(default_factory=dict)


def _why_ended(access: dict[str, Any]) -> str:
    """Why the caller's turn ended, as the lab's heartbeat answer says (``turnEnded``)."""
    why = access.get("turnEnded")
    return str(why) if why else "the turn ended (time limit, a teacher, or the rig's fault)"


class Turn:
    """This script's turn at a rig: commands, readings, runs; released on exit.

    While it is held a thread keeps it alive (a heartbeat each third of the
    lab's client timeout). While nobody waits, the turn is extended in its
    last minute as far as the lab allows (``POST .../control/more-time``);
    once someone queues, the script is told on standard error how long it
    has left. :meth:`release` (or leaving the ``with`` block, normally or by
    an exception) ends it, and the lab puts the rig's input at its safe value
    for the next user.

    Parameters
    ----------
    lab : Lab
    rig : dict
        The rig as the lab answered when control was granted.
    extend : bool
        Extend the turn while nobody waits (default ``True``).
    """

    def __init__(self, lab: Lab, rig: dict[str, Any], *, extend: bool = True) -> None:
        self.lab = lab
        self.rig = rig
        self.rig_id: str = rig["id"]
        self.lost: str | None = None
        self.extend = extend
        self._told_queue = False
        self._released = threading.Event()
        interval = max(0.5, float(rig["limits"]["clientTimeout"]) / 3.0)
        self._beat = threading.Thread(
            target=self._keep_alive, args=(interval,), name=f"turn-{self.rig_id}", daemon=True
        )
        self._beat.start()

    @property
    def held(self) -> bool:
        """Whether the turn is (as far as the client knows) still this script's."""
        return not self._released.is_set() and self.lost is None

    def check(self) -> None:
        """Raise :class:`TurnEndedError` (naming why) if the lab ended the turn."""
        if self.lost is not None:
            raise TurnEndedError(self.rig_id, self.lost)

    def _keep_alive(self, interval: float) -> None:
        while not self._released.wait(interval):
            try:
                rig = self.lab.request("POST", f"/api/rigs/{self.rig_id}/heartbeat")
            except LabRequestError as exc:
                if exc.status is not None:  # the lab answered no: the turn is gone
                    self.lost = exc.detail
                    return
                continue  # a network blip: try again next time
            access = rig["access"]
            if access["role"] != "controller":
                self.lost = _why_ended(access)
                return
            self._watch_queue(access)

    def refused(self, exc: LabRequestError) -> None:
        """Mark the turn lost if the lab refused ``exc``'s request because the turn ended.

        The lab's heartbeat answer says whether the turn is still this script's
        and, if not, why it ended (a teacher, the time limit...): a refusal for
        another cause (a run going) leaves the turn held.
        """
        if self.lost is not None or exc.status not in (401, 403, 409):
            return
        if exc.status == 401:  # the token is gone: its detail says so (revoked, expired)
            self.lost = exc.detail
            return
        try:
            rig = self.lab.request("POST", f"/api/rigs/{self.rig_id}/heartbeat")
        except LabRequestError as again:
            if again.status is not None:
                self.lost = again.detail
            return
        if rig["access"]["role"] != "controller":
            self.lost = _why_ended(rig["access"])

    def _watch_queue(self, access: dict[str, Any]) -> None:
        waiting = int(access.get("queueSize") or 0)
        left = access.get("timeLeft")
        if waiting and not self._told_queue:
            about = f" ends in {left:.0f} s" if isinstance(left, int | float) else " is limited"
            print(
                f"rig {self.rig_id!r}: {waiting} waiting in the queue; this script's turn{about} "
                "(no more extensions while someone waits)",
                file=sys.stderr,
                flush=True,
            )
        self._told_queue = bool(waiting)
        if self.extend and not waiting and access.get("canExtend"):
            # Refused (the lab's limit of extensions, someone just queued): the turn ends on time.
            with contextlib.suppress(LabRequestError):
                self.lab.request("POST", f"/api/rigs/{self.rig_id}/control/more-time")

    def set_input(self, u: float) -> float | None:
        """Set the rig's input; return the value the device applied (``None``: none)."""
        answer = self.lab.request("PUT", f"/api/rigs/{self.rig_id}/input", json={"u": float(u)})
        applied = answer.get("applied")
        return None if applied is None else float(applied)

    def set_channel(self, name: str, level: float) -> float | None:
        """Set one of the rig's further inputs (a kit's heater 2, ``q2``); return the level set.

        ``None``: it reached no device. The lab refuses (422) an input the rig
        does not have (``channel_not_on_rig``) or a level outside its range.
        """
        answer = self.lab.request(
            "PUT", f"/api/rigs/{self.rig_id}/channels/{name}", json={"level": float(level)}
        )
        applied = answer.get("applied")
        return None if applied is None else float(applied)

    def pace(self, speedup: float) -> float:
        """Run the rig (a twin) at ``speedup`` until this turn ends; return the speed-up in force.

        Raises
        ------
        LabRequestError
            422 ``speedup_refused`` naming the rig and what it allows (hardware
            runs in real time; a twin allows 1 up to its teacher's ``twin_speedup``),
            409 while a run is going.
        """
        body = {"speedup": float(speedup)}
        rig = self.lab.request("PUT", f"/api/rigs/{self.rig_id}/control/speedup", json=body)
        return float(rig.get("speedup") or speedup)

    def read(self) -> Reading:
        """Read the rig's output now."""
        body = self.lab.request("GET", f"/api/rigs/{self.rig_id}/reading")
        at = body.get("at")
        return Reading(
            body.get("y"),
            datetime.fromisoformat(at) if isinstance(at, str) else None,
            body.get("u"),
            str(body.get("unit", "")),
            bool(body.get("fresh")),
            dict(body.get("channels") or {}),
        )

    def start_run(
        self,
        dt: float,
        samples: int,
        *,
        signal: str | None = None,
        setpoint: float | None = None,
        methods: Sequence[str] = ("srm", "lsm"),
        input: str = "u",
        output: str = "y",
        **settings: Any,
    ) -> dict[str, Any]:
        """START a run (the lab's panels); ``settings`` are the registry's (``window``...).

        ``input``, ``output``: the pair the run identifies, by the rig's channel names
        (a kit's ``"q2"``, ``"t2"``: the signal drives heater 2, the methods are fed
        sensor 2); default the rig's ``u`` and ``y``.

        Raises
        ------
        InvalidParameterError
            For a setting the lab does not take (the allowed ones named).
        LabRequestError
            If the lab refuses a value (422 naming it) or the turn is over.
        """
        allowed = {s["name"] for s in self.lab.methods()["runSettings"]} | {"offset"}
        unknown = sorted(set(settings) - allowed)
        if unknown:
            raise InvalidParameterError(
                f"unknown run setting(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(sorted(allowed))}"
            )
        body: dict[str, Any] = {"dt": dt, "samples": samples, "methods": list(methods), **settings}
        if signal is not None:
            body["signal"] = signal
        if setpoint is not None:
            body["setpoint"] = setpoint
        if (input, output) != ("u", "y"):  # the standard pair is the lab's default
            body |= {"input": input, "output": output}
        path = f"/api/rigs/{self.rig_id}/runs"
        answer: dict[str, Any] = self.lab.request("POST", path, json=body)
        return answer

    def stop_run(self) -> dict[str, Any]:
        """END the current run (final estimates computed, data kept)."""
        answer: dict[str, Any] = self.lab.request(
            "POST", f"/api/rigs/{self.rig_id}/runs/current/stop"
        )
        return answer

    def release(self) -> None:
        """End the turn (idempotent): the lab makes the rig safe and hands it to the next."""
        if self._released.is_set():
            return
        self._released.set()
        self.lab._leave(self.rig_id)

    def __enter__(self) -> Turn:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
