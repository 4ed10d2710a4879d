"""The lab's error sentences in the reader's language (gettext catalogues via Babel).

Every error the lab answers carries a stable ``code`` (``http/errors.py``);
``ERROR_SENTENCES`` gives each code one English sentence, the gettext
``msgid``, and ``locale/<language>/LC_MESSAGES/thermolab.po`` its
translations (pt-BR, es; the English catalogue is the template). The ``.po``
sources are read with Babel when first needed — nothing is compiled at
install, so ``pip install -e .`` keeps working with nothing else.

The language of an answer is the reader's choice (the ``thermolab_lang``
cookie or an explicit ``Accept-Language`` the page sends), negotiated against
``LANGUAGES`` like the browser does: an exact tag, then the same primary
language (``pt``, ``pt-PT`` -> pt-BR), else English. The command line takes it
from ``LANGUAGE`` / ``LC_ALL`` / ``LC_MESSAGES`` / ``LANG``.
"""

from __future__ import annotations

import gettext
import io
from collections.abc import Mapping
from functools import cache
from pathlib import Path

from babel.messages.mofile import write_mo
from babel.messages.pofile import read_po
from babel.numbers import get_decimal_symbol

__all__ = [
    "DEFAULT_LANGUAGE",
    "ERROR_SENTENCES",
    "LANGUAGES",
    "LANGUAGE_COOKIE",
    "decimal_mark",
    "error_message",
    "language_from_environment",
    "negotiate_language",
    "translate",
]

LANGUAGES = ("pt-BR", "en", "es")
DEFAULT_LANGUAGE = "en"
LANGUAGE_COOKIE = "thermolab_lang"
_LOCALE_DIR = Path(__file__).with_name("locale")
_DOMAIN = "thermolab"

# One sentence per stable error code: what happened, in words a student reads.
# The answer's ``detail`` keeps the precise English reason beside it.
ERROR_SENTENCES: Mapping[str, str] = {
    "access_denied": "You are not allowed to do this.",
    "bad_request": "The request could not be handled.",
    "body_too_large": "The request is too large.",
    "camera_unavailable": "The rig's image is not available now.",
    "conflict": "This clashes with the lab's current state.",
    "cross_origin": "Requests that change something must come from the lab's own pages.",
    "database_unavailable": (
        "The lab cannot reach its database just now; try again in a few seconds."
    ),
    "extend_refused": "Your turn cannot be extended now.",
    "http_error": "The request could not be handled.",
    "invalid_parameter": "A value is not allowed.",
    "invalid_request": "The request is not valid.",
    "method_not_allowed": "This action is not allowed here.",
    "name_taken": "This user name is already taken.",
    "not_authenticated": "You are not logged in, or the user name or password is wrong.",
    "not_found": "Nothing was found there.",
    "rate_limited": "Too many attempts: wait a moment and try again.",
    "rig_unavailable": "The rig is not available now.",
    "turn_ended": "Your turn has ended.",
    # Courses and people (issue #10).
    "class_list_invalid": "The class list has bad lines; nothing was changed.",
    "enrol_code_wrong": "No course has this enrolment code.",
    "course_closed": "This course is closed for the term: it can be read, not changed.",
    "course_name_taken": "Another course already has this name: choose another one.",
    "password_change_required": "Choose a new password before going on.",
    "setting_out_of_range": "A setting is outside the range this rig allows.",
    "setting_not_for_rig": "This rig does not have that setting.",
    "speedup_refused": "This rig does not allow that speed-up.",
    "channel_not_on_rig": "This rig does not have that input (a second heater, a fan).",
    "loop_pair_not_on_rig": "This rig has no such heater and sensor pair for the closed loop.",
    "channel_in_loop": (
        "The closed loop drives this heater: set the other one, or switch the loop to manual."
    ),
    "pair_channel_unknown": (
        "This rig has no channel of that name: choose the pair among its inputs and outputs."
    ),
    "pair_wrong_role": (
        "The pair's input must be one of the rig's heaters (inputs) and its output one of its "
        "sensors (outputs)."
    ),
    "model_pair_mismatch": (
        "This run identified another heater and sensor pair: tune the loop with a model of "
        "its own pair."
    ),
    "settings_changed": "Someone changed these settings meanwhile: load them again.",
    # The closed loop and the runs' precise conflicts.
    "gain_out_of_range": "A controller setting is not a finite number within its published range.",
    "no_output_unit": "This rig has no measured output, so it cannot be controlled in closed loop.",
    "no_run": "No run is going on this rig.",
    "not_closed_loop": "The run was started without a controller.",
    "previous_run_ending": "The previous turn's run is still ending: try again in a few seconds.",
    # Why a rig takes no turn now, and a controller's action by someone else (issue #24).
    "rig_out_of_service": "The rig is out of service: ask a teacher.",
    "rig_fault_not_cleared": "The rig has a fault: a teacher must clear it before anyone uses it.",
    "lab_starting": "The lab is still starting: try again in a few seconds.",
    "host_offline": "The computer this rig is connected to is offline: try again later.",
    "not_controller": "You do not control this rig now.",
    "nobody_controls": "Nobody controls this rig now.",
    # A run an assignment does not take (issue #24).
    "handin_wrong_rig": "This run was made on another rig than the assignment's.",
    "handin_unfinished": "This run did not run to its end: hand in one that did.",
    "handin_too_short": "This run has too few samples to be marked.",
    # A teacher's and an administrator's clashes (errors.CONFLICT_CASES).
    "group_name_taken": "This course already has a lab group with this name.",
    "already_in_group": "Someone in this group is already in another lab group of the course.",
    "course_open": "This course is still open: close it first.",
    "leavers_changed": (
        "The list of students to remove changed since it was shown: look at it again."
    ),
    "class_list_changed": (
        "The accounts changed while the class list was being imported: upload it again."
    ),
    "platform_registered": "This LMS is registered already.",
    "member_has_other_role": (
        "This person already has another role in the course: remove them from it first."
    ),
    "token_limit": "You have as many access tokens as allowed: revoke one first.",
    "person_at_rig": (
        "This person is at a rig's controls or waiting for one: remove them when they are done."
    ),
    "pace_fixed_during_run": (
        "A run is going on this rig: its pace changes only before the next START."
    ),
    "not_in_line": "This person neither controls this rig nor waits for it.",
    "rig_no_device": "This rig has no device attached: a run needs one.",
    "nothing_handed_in": "This student has handed nothing in: there is no mark to change.",
    "stored_meanwhile": "Something else was stored meanwhile: look again and retry.",
    "run_in_progress": "A run of your turn is already going: END it first.",
    "setpoint_out_of_range": "The set point is outside the rig's output range.",
    "setpoint_no_step": (
        "The set point is the output the step starts from: there is no step to tune for. "
        "Choose a set point away from it."
    ),
    # Bookings (issue #10, item 5).
    "booking_clash": "This slot overlaps another booking of the same rig.",
    "rig_booked": "The rig is booked for another course's slot now.",
    # Slot times and the booking tools (issue #24, item 7).
    "slot_ends_before_start": (
        "The slot ends before it starts: check the start and end times (and the day)."
    ),
    "slot_too_long": (
        "The slot is longer than a day: say that it is longer on purpose, or shorten it."
    ),
    "slot_zone_missing": "The slot's times must carry their time zone.",
    "time_zone_unknown": "The time zone is not a known IANA time zone (like America/Sao_Paulo).",
    "booking_quota_exceeded": "This booking would pass your course's weekly booking quota.",
    "booking_series_clash": (
        "Some weeks of this series overlap other bookings; nothing was booked."
    ),
    # The LTI 1.3 tool (issue #12).
    "lti_invalid_token": (
        "The LMS's sign-in could not be verified (forged, expired or meant for another tool)."
    ),
    "lti_replayed": (
        "This launch from the LMS was used already: open the activity again in the LMS."
    ),
    "lti_state_invalid": (
        "This launch was not started in this browser, or took too long: open the activity"
        " again in the LMS."
    ),
    "lti_unknown_platform": (
        "This LMS is not registered with the lab: ask a teacher to register it."
    ),
    "lti_unknown_deployment": (
        "This installation of the lab in the LMS is not registered: ask a teacher to add "
        "its deployment id."
    ),
    "lti_jwks_unreachable": (
        "The LMS's keys could not be fetched, so its sign-in could not be verified."
    ),
    "lti_service_failed": "The LMS did not answer as expected; try again later.",
    "lti_cookies_blocked": (
        "Your browser blocks the lab's cookies inside the LMS: open the lab in a new window."
    ),
    "lti_returning": "Returning to the LMS with your choice.",
    # LTI as the IMS certification checks it (issue #25).
    "lti_claim_invalid": (
        "The LMS's launch lacks information the lab needs (roles or the activity's link)."
    ),
    "lti_target_invalid": "This launch was meant for another tool's address.",
    "lti_form_too_large": "The LMS sent too much data with this launch.",
    # Pictures of the guide pages (issue #10, item 1).
    "image_invalid": "The file is not a picture the lab can read, or it is damaged.",
    "image_type_unsupported": "Only PNG, JPEG, GIF and WebP pictures are accepted.",
    "image_too_large": (
        "The picture's file is too large: save it smaller (as JPEG, for a photo) and try again."
    ),
    "image_too_many_pixels": "The picture has too many pixels: scale it down and try again.",
}


def _po_path(language: str) -> Path:
    return _LOCALE_DIR / language.replace("-", "_") / "LC_MESSAGES" / f"{_DOMAIN}.po"


@cache
def _translations(language: str) -> gettext.NullTranslations:
    path = _po_path(language)
    if not path.is_file():
        return gettext.NullTranslations()
    with path.open("rb") as source:
        catalog = read_po(source, locale=language.replace("-", "_"))
    compiled = io.BytesIO()
    write_mo(compiled, catalog)
    compiled.seek(0)
    return gettext.GNUTranslations(compiled)


def translate(message: str, language: str) -> str:
    """``message`` (an English msgid) in ``language``; English when it has no translation."""
    return _translations(language).gettext(message)


def decimal_mark(language: str) -> str:
    """The decimal mark of ``language`` ("," in pt-BR and es), for numbers the server writes.

    Examples
    --------
    >>> decimal_mark("pt-BR"), decimal_mark("en")
    (',', '.')
    """
    return str(get_decimal_symbol(language.replace("-", "_")))


def error_message(code: str, language: str = DEFAULT_LANGUAGE) -> str:
    """The sentence of an error ``code`` in ``language`` (a generic one for an unknown code).

    Examples
    --------
    >>> error_message("turn_ended", "pt-BR")
    'Sua vez terminou.'
    >>> error_message("turn_ended", "en")
    'Your turn has ended.'
    """
    sentence = ERROR_SENTENCES.get(code, ERROR_SENTENCES["bad_request"])
    return translate(sentence, language)


def _match(tag: str) -> str | None:
    wanted = tag.strip().lower().replace("_", "-")
    if not wanted or wanted == "*":
        return None
    for language in LANGUAGES:
        if language.lower() == wanted:
            return language
    primary = wanted.split("-")[0]
    for language in LANGUAGES:
        if language.lower().split("-")[0] == primary:
            return language
    return None


def negotiate_language(accept_language: str | None, chosen: str | None = None) -> str:
    """The language to answer in: the reader's ``chosen`` one, else the best of ``Accept-Language``.

    Examples
    --------
    >>> negotiate_language("es-MX,es;q=0.9,en;q=0.5")
    'es'
    >>> negotiate_language("fr, pt;q=0.8")
    'pt-BR'
    >>> negotiate_language("en", chosen="pt-BR")
    'pt-BR'
    >>> negotiate_language(None)
    'en'
    """
    if chosen:
        match = _match(chosen)
        if match is not None:
            return match
    ranked: list[tuple[float, int, str]] = []
    for position, part in enumerate((accept_language or "").split(",")):
        tag, _, params = part.partition(";")
        quality = 1.0
        params = params.strip()
        if params.startswith("q="):
            try:
                quality = float(params[2:])
            except ValueError:
                quality = 0.0
        if quality > 0:
            ranked.append((-quality, position, tag))
    for _, _, tag in sorted(ranked):
        match = _match(tag)
        if match is not None:
            return match
    return DEFAULT_LANGUAGE


def language_from_environment(environ: Mapping[str, str]) -> str:
    """The command line's language, from the POSIX locale variables (``pt_BR.UTF-8`` -> pt-BR)."""
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES", "LANG"):
        value = environ.get(name, "")
        for tag in value.split(":"):
            tag = tag.split(".")[0].split("@")[0]
            if tag in ("C", "POSIX"):
                return DEFAULT_LANGUAGE
            match = _match(tag)
            if match is not None:
                return match
    return DEFAULT_LANGUAGE
