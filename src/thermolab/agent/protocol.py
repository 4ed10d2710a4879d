"""The wire protocol between a lab and its rig hosts (``thermolab agent``), declared once.

Both ends import this module: the agent (:mod:`thermolab.agent`, rigs and
runner side) and the lab (:mod:`thermolab.lab.agents`). It sits in the
``thermolab.agent`` layer, below the lab and above the runner, so that the
agent never imports the lab and the lab never re-declares a message.

Every message is one JSON text frame, a pydantic model with a ``type``
discriminator. The agent dials the lab (``wss://LAB/api/agents/link``) and
speaks first (:class:`Hello`, with its rig's secret); the lab answers
:class:`Welcome` or closes the
socket with :data:`CLOSE_REFUSED`.

Durable upward messages (:class:`SampleOut`, :class:`RunEnded`) carry a
``seq`` that numbers the agent's outbox; the lab stores them idempotently
and answers :class:`Ack` with the highest ``seq`` it holds, and the agent
forgets only what is acknowledged (:mod:`thermolab.agent.outbox`).

A closed-loop run: :class:`StartRun` carries the run's
:class:`~thermolab.runner.control_request.ControlRequest` as it is (the
control layer's declaration, checked by the host as by the lab), each live
command of the loop is one message (:class:`SetMode`, :class:`SetSetpoint`,
:class:`SetGains` with :class:`~thermolab.control.PIDGains`, :class:`SetFan`),
each sample carries the loop's channels (``extra``), the heartbeat the loop's
state, and :class:`RunEnded` the controller as it ended.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from thermolab.control import PIDGains
from thermolab.runner.control_request import ControlRequest

__all__ = [
    "AGENT_LINK_PATH",
    "CLOSE_NOT_OWNER",
    "CLOSE_REFUSED",
    "HELLO_HOLD",
    "LINK_LOST",
    "OWNER_GONE",
    "PROTOCOL_VERSION",
    "Ack",
    "AgentMessage",
    "EndRun",
    "Heartbeat",
    "Hello",
    "LabMessage",
    "LoopCommand",
    "Power",
    "RunEnded",
    "SampleBatch",
    "SampleOut",
    "SetChannel",
    "SetFan",
    "SetGains",
    "SetInput",
    "SetMode",
    "SetSetpoint",
    "StartRun",
    "Welcome",
    "decode_agent",
    "decode_lab",
    "encode",
]

PROTOCOL_VERSION = 2
"""Bumped on an incompatible change; the lab refuses an agent speaking another."""
AGENT_LINK_PATH = "/api/agents/link"
"""Where an agent dials in on the lab."""
CLOSE_REFUSED = 4401
"""WebSocket close code: unknown rig, wrong secret or protocol version."""
CLOSE_NOT_OWNER = 4409
"""WebSocket close code: this web worker does not own the rigs (a follower); dial another."""
LINK_LOST = "link to the lab lost"
"""How a ``RunEnded.message`` begins when the host ENDed the run for its lost link (its grace):
no address of the lab answered at all (the network away, or the lab's machine)."""
OWNER_GONE = "no lab worker owned the rigs"
"""How a ``RunEnded.message`` begins when the host ENDed the run at its grace's end while
the lab's machines answered (a worker that does not own the rigs, a refused connection, a
hung worker): the owner worker was gone and no standby took over in time. Old hosts say
:data:`LINK_LOST` for this too."""
HELLO_HOLD = 20.0
"""Seconds a lab worker may hold a host's ``Hello`` unanswered; the host waits longer.

A standby worker holds a host that dials it while no owner is heard (a
takeover: at most the lease's 15 s and two announcements) and answers once
the new owner is decided: ``Welcome`` if it took the rigs over,
:data:`CLOSE_NOT_OWNER` otherwise.
"""

_Finite = Annotated[float, Field(allow_inf_nan=False)]
_Channel = Annotated[str, Field(min_length=1, max_length=32)]

# Fields added since protocol 2 first shipped: left out of a frame while unset, so that a
# host of an earlier release still reads every message that does not use them.
_LEFT_OUT_WHEN_UNSET = frozenset({"pair"})


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# -- agent -> lab ---------------------------------------------------------------------------


class Hello(_Message):
    """The agent's first message: who it is and its secret."""

    type: Literal["hello"] = "hello"
    rig: str = Field(min_length=1, max_length=64)
    secret: str = Field(min_length=16, max_length=200)
    protocol: int
    version: str = Field(max_length=64)
    spec: str = Field(max_length=200)
    speedup: _Finite = Field(
        default=1.0,
        gt=0,
        description="times real time the host's rig runs (--speedup of a twin; 1 for hardware)",
    )
    host: str = Field(
        default="",
        max_length=200,
        description=(
            "this host process (machine:pid:tag): a second one for a rig already linked is "
            "refused; the same one redialling replaces its old link"
        ),
    )


class Heartbeat(_Message):
    """Sent every second: the agent is alive, and the rig as it is now."""

    type: Literal["heartbeat"] = "heartbeat"
    powered: bool
    u: _Finite | None = None
    y: float | None = None  # a sensor may read NaN: the lab judges it (health)
    fault: str | None = Field(default=None, max_length=500)
    run: int | None = None
    pending: int = Field(ge=0, description="outbox messages not yet acknowledged")
    loop: dict[str, Any] | None = Field(
        default=None, description="the run's control loop now (ControlLoop.to_dict), if any"
    )


class SampleOut(_Message):
    """One sample of a run, as the agent's runner took it."""

    seq: int = Field(ge=1)
    run: int = Field(ge=1)
    k: int = Field(ge=0)
    t: float
    u: float
    y: float
    t_read: float
    jitter: float
    lateness: float
    extra: dict[str, float | None] | None = Field(
        default=None, description="the run's extra channels (a closed loop's), by name"
    )


class SampleBatch(_Message):
    """Samples in ``seq`` order (live ones, or a backlog after a link loss)."""

    type: Literal["samples"] = "samples"
    samples: list[SampleOut]


class RunEnded(_Message):
    """A run ended on the agent (after its last sample in ``seq`` order)."""

    type: Literal["run_ended"] = "run_ended"
    seq: int = Field(ge=1)
    run: int = Field(ge=1)
    reason: str = Field(max_length=32, description="thermolab.runner.EndReason value")
    message: str = Field(default="", max_length=500)
    samples: int = Field(ge=0)
    control: dict[str, Any] | None = Field(
        default=None, description="a closed loop's controller as it ended (ControlLoop.to_dict)"
    )


AgentMessage = Annotated[Hello | Heartbeat | SampleBatch | RunEnded, Field(discriminator="type")]
"""Anything an agent sends."""


# -- lab -> agent ---------------------------------------------------------------------------


class Welcome(_Message):
    """The lab accepted the agent.

    The agent then sends its whole outbox again: what the lab already stored
    is ignored there, so an Ack lost with the link costs a resend, never a sample.
    """

    type: Literal["welcome"] = "welcome"
    grace: float = Field(gt=0, description="seconds a run outlives a lost link")


class Ack(_Message):
    """Everything up to ``seq`` is stored on the lab: the agent may forget it."""

    type: Literal["ack"] = "ack"
    seq: int = Field(ge=0)


class StartRun(_Message):
    """START a run with the lab's run id; the settings were checked by the lab."""

    type: Literal["start_run"] = "start_run"
    run: int = Field(ge=1)
    dt: float = Field(gt=0)
    samples: int = Field(ge=1)
    signal: str | None = Field(default=None, max_length=2000)
    input: _Finite | None = None
    control: ControlRequest | None = Field(
        default=None, description="a closed-loop run's controller (checked again by the host)"
    )
    pair: tuple[_Channel, _Channel] | None = Field(
        default=None,
        description=(
            "the pair (input, output) the run identifies when not the rig's standard u -> y "
            "(a kit's q2 -> t2): the signal drives that input (checked again by the host)"
        ),
    )


class EndRun(_Message):
    """END the run (its controller, a teacher, or the end of the turn)."""

    type: Literal["end_run"] = "end_run"
    run: int = Field(ge=1)


class SetInput(_Message):
    """A controller's input: to the run ``run`` if given, else to the idle rig."""

    type: Literal["set_input"] = "set_input"
    u: _Finite
    run: int | None = None


class SetMode(_Message):
    """Switch the run's controller: AUTO (with a new set point) or MANUAL (holding ``u``)."""

    type: Literal["set_mode"] = "set_mode"
    run: int = Field(ge=1)
    auto: bool
    setpoint: _Finite | None = None
    u: _Finite | None = None


class SetSetpoint(_Message):
    """A new set point for the run's controller."""

    type: Literal["set_setpoint"] = "set_setpoint"
    run: int = Field(ge=1)
    setpoint: _Finite


class SetGains(_Message):
    """New gains for the run's controller (bumpless)."""

    type: Literal["set_gains"] = "set_gains"
    run: int = Field(ge=1)
    gains: PIDGains


class SetFan(_Message):
    """Run the rig's disturbance fan at ``percent`` during the run."""

    type: Literal["set_fan"] = "set_fan"
    run: int = Field(ge=1)
    percent: _Finite


class SetChannel(_Message):
    """A further input's level (a kit's heater 2, ``q2``): to run ``run``, else the idle rig."""

    type: Literal["set_channel"] = "set_channel"
    name: str = Field(min_length=1, max_length=40)
    level: _Finite
    run: int | None = Field(default=None, ge=1)


LoopCommand = SetMode | SetSetpoint | SetGains | SetFan | SetChannel
"""A closed-loop command to the run going on the host."""


class Power(_Message):
    """Power the rig on or off (off: actuator at its safe value)."""

    type: Literal["power"] = "power"
    on: bool


_LabUnion = Welcome | Ack | StartRun | EndRun | SetInput | Power | LoopCommand
LabMessage = Annotated[_LabUnion, Field(discriminator="type")]
"""Anything the lab sends."""

_AGENT: TypeAdapter[Hello | Heartbeat | SampleBatch | RunEnded] = TypeAdapter(AgentMessage)
_LAB: TypeAdapter[_LabUnion] = TypeAdapter(LabMessage)


def encode(message: _Message) -> str:
    """Return the message as its JSON text frame."""
    unset = {name for name in _LEFT_OUT_WHEN_UNSET if getattr(message, name, 0) is None}
    return message.model_dump_json(exclude=unset or None)


def decode_agent(text: str | bytes) -> Hello | Heartbeat | SampleBatch | RunEnded:
    """Parse a frame from an agent (``pydantic.ValidationError`` if it is not one)."""
    return _AGENT.validate_json(text)


def decode_lab(text: str | bytes) -> _LabUnion:
    """Parse a frame from the lab (``pydantic.ValidationError`` if it is not one)."""
    return _LAB.validate_json(text)
