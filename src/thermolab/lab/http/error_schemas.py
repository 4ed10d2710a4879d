"""JSON bodies of the lab's refusals: every 4xx answer, and a 422's problems one by one.

The stable codes a client may act on are declared here, in the answers' schema
(:mod:`.errors` maps each error class to its status and code).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from thermolab.lab.http.bodies import Out as _Out

__all__ = ["ErrorOut", "ProblemOut", "ValidationErrorOut"]


class ErrorOut(_Out):
    """Every 4xx answer: ``detail`` says what was wrong and what is allowed; ``code`` is stable."""

    detail: str
    code: str = Field(
        description="stable name of the error: not_authenticated, access_denied, "
        "cross_origin, not_found, method_not_allowed, conflict, turn_ended, run_in_progress, "
        "previous_run_ending, rig_unavailable, body_too_large, rate_limited, "
        "camera_unavailable..."
    )
    message: str | None = Field(
        default=None,
        description="the code's sentence in the reader's language (the thermolab_lang cookie, "
        "else Accept-Language; Content-Language names it)",
    )


class ProblemOut(_Out):
    """One problem of a request that was refused with 422."""

    loc: list[str] = Field(
        description="where: ['body', field...], ['path', name], ['query', name]; "
        "empty when the problem is the settings together"
    )
    type: str = Field(description="pydantic's error type, or the error's code")
    msg: str
    params: dict[str, str | int] | None = Field(
        None, description="a class list's problem: the values its sentence names"
    )
    message: str | None = Field(None, description="a class list's problem in the reader's language")


class ValidationErrorOut(_Out):
    """Every 422 (a body, path or query value the API refuses): ``detail`` in words,
    ``errors`` one per problem."""

    detail: str
    code: Literal[
        "invalid_request",
        "invalid_parameter",
        "class_list_invalid",
        "gain_out_of_range",
        "setpoint_out_of_range",
        "setpoint_no_step",
        "no_output_unit",
        "setting_out_of_range",
        "image_invalid",
        "image_too_many_pixels",
        "setting_not_for_rig",
        "speedup_refused",
        "channel_not_on_rig",
        "loop_pair_not_on_rig",
        "pair_channel_unknown",
        "pair_wrong_role",
        "model_pair_mismatch",
        "slot_ends_before_start",
        "slot_too_long",
        "slot_zone_missing",
        "time_zone_unknown",
    ] = Field(
        description="invalid_request: the request does not match the schema (a body that is "
        "not UTF-8 JSON included); invalid_parameter: the values match the schema but the lab "
        "refuses them (a signal outside the rig's range, a run too long...); "
        "class_list_invalid: a class list with bad lines (one entry of errors per line); "
        "gain_out_of_range, setpoint_out_of_range, setpoint_no_step, no_output_unit: the "
        "closed loop's refusals; "
        "setting_out_of_range: a teacher setting outside the rig's allowed range (the message "
        "names the range); image_invalid, image_too_many_pixels: a guide picture that is not "
        "a readable picture, or has too many pixels; setting_not_for_rig: a setting this rig "
        "does not have (the twin speed-up of hardware or of a rig host's twin); "
        "speedup_refused: a script's speed-up the rig does not allow (the message names what "
        "it allows); channel_not_on_rig: an input the rig does not have (a second heater on a "
        "one-heater rig; the message names what it has); loop_pair_not_on_rig: a closed "
        "loop's heater and sensor the rig does not pair; pair_channel_unknown, pair_wrong_role: "
        "a run's input/output pair naming a channel the rig lacks, or an input that is no "
        "recorded actuator or an output that is no sensor; model_pair_mismatch: a tuning "
        "table asked for a loop whose heater and sensor are not the pair the run identified; "
        "slot_ends_before_start, "
        "slot_too_long, slot_zone_missing: a booking's "
        "times (an end at or before the start, longer than a day unless said longer, a time "
        "without its zone); time_zone_unknown: a time zone that is not a known IANA name "
        "(a weekly series' zone)"
    )
    message: str | None = Field(
        default=None, description="the code's sentence in the reader's language"
    )
    errors: list[ProblemOut]
