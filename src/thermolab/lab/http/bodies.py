"""The base models of the lab's JSON bodies: camelCase on the wire, strict requests.

Request bodies (:class:`In`) refuse unknown fields and values of the wrong
type, so a typo is a 422 naming the field rather than a silently ignored
setting; answers (:class:`Out`) accept either spelling when built.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict
from pydantic.alias_generators import to_camel

__all__ = ["In", "Out"]


class In(BaseModel):
    """A request body."""

    model_config = ConfigDict(
        alias_generator=to_camel, populate_by_name=True, extra="forbid", strict=True
    )


class Out(BaseModel):
    """An answer body."""

    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True)
