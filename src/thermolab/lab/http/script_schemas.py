"""JSON bodies of what scripts use: API tokens, the lab's version, a rig's reading."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from pydantic import Field

from thermolab.lab.accounts.tokens import (
    DEFAULT_TOKEN_DAYS,
    MAX_TOKEN_DAYS,
    MAX_TOKEN_NAME,
    TokenInfo,
)
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.outcomes import OutputReading
from thermolab.lab.runs.channels import ChannelResult

__all__ = ["LabVersionOut", "NewTokenOut", "ReadingOut", "SpeedupIn", "TokenIn", "TokenOut"]


class SpeedupIn(In):
    """A twin's speed-up for the caller's turn (``setup(connected=False, speedup=...)``)."""

    speedup: Annotated[
        float,
        Field(
            gt=0,
            allow_inf_nan=False,
            description="times real time; from 1 up to the twin's twin_speedup",
        ),
    ]


class TokenIn(In):
    """A new personal API token."""

    name: Annotated[str, Field(min_length=1, max_length=MAX_TOKEN_NAME, description="a label")]
    read_only: bool = Field(False, description="GET requests only")
    days: Annotated[int, Field(ge=1, le=MAX_TOKEN_DAYS, description="lifetime in days")] = (
        DEFAULT_TOKEN_DAYS
    )


class TokenOut(Out):
    """A token as its owner sees it (never the secret)."""

    id: int
    name: str
    prefix: str = Field(description="the secret's first characters, to recognise it")
    read_only: bool
    created_at: datetime
    last_used_at: datetime | None
    expires_at: datetime | None

    @classmethod
    def of(cls, info: TokenInfo) -> TokenOut:
        """Build from a token's description."""
        return cls(
            id=info.id,
            name=info.name,
            prefix=info.prefix,
            read_only=info.read_only,
            created_at=info.created_at,
            last_used_at=info.last_used_at,
            expires_at=info.expires_at,
        )


class NewTokenOut(TokenOut):
    """A token just created, with its secret: shown this once, never again."""

    token: str = Field(description="the secret: send it as 'Authorization: Bearer <token>'")


class LabVersionOut(Out):
    """What a client checks before speaking to the lab (``thermolab.api_version``)."""

    name: str = Field(description="always 'thermolab'")
    title: str
    version: str = Field(description="the lab's package version")
    api: str = Field(description="the API version, MAJOR.MINOR")


class ReadingOut(Out):
    """A rig's output (``fresh``: read from the device for this request, the controller's)."""

    rig: str
    y: float | None = Field(description="the output in the rig's unit; null if never read")
    at: datetime | None
    u: float | None = Field(description="the input the lab last applied")
    unit: str
    fresh: bool
    channels: dict[str, float | None] = Field(
        default_factory=dict,
        description="the rig's further channels: outputs read with y (a kit's t2), inputs at "
        "their level (q2); empty for a rig that has none",
    )

    @classmethod
    def of(cls, reading: OutputReading, unit: str) -> ReadingOut:
        """Build from a reading."""
        return cls(
            rig=reading.rig_id,
            y=reading.y,
            at=reading.at,
            u=reading.u,
            unit=unit,
            fresh=reading.fresh,
            channels=dict(reading.channels),
        )


class ChannelIn(In):
    """A further input's new level (a kit's heater 2, %), within the range the rig declares."""

    level: Annotated[float, Field(allow_inf_nan=False, description="the new level")]


class ChannelOut(Out):
    """An accepted level of a further input."""

    rig: str
    name: str
    level: float
    applied: float | None = Field(
        description="the level set (by the device, or the run's next sample); null if none"
    )
    run: int | None = Field(description="the run it went to, if one is going")

    @classmethod
    def of(cls, result: ChannelResult) -> ChannelOut:
        """Build from the lab's result."""
        return cls(
            rig=result.rig_id,
            name=result.name,
            level=result.level,
            applied=result.applied,
            run=result.run_id,
        )
