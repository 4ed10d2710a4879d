"""The LTI 1.3 claims the tool reads and writes, and the mapping of LMS roles.

The names are those of IMS LTI Core 1.3, Deep Linking 2.0, NRPS 2.0 and AGS 2.0.
"""

from __future__ import annotations

from collections.abc import Iterable

from thermolab.lab.db.models import MemberRole, Role

__all__ = [
    "AGS_SCOPES",
    "CLAIM",
    "DEEP_LINKING_REQUEST",
    "DEEP_LINKING_RESPONSE",
    "LTI_VERSION",
    "NRPS_SCOPE",
    "RESOURCE_LINK_REQUEST",
    "course_role",
    "lab_role",
]

LTI_VERSION = "1.3.0"
RESOURCE_LINK_REQUEST = "LtiResourceLinkRequest"
DEEP_LINKING_REQUEST = "LtiDeepLinkingRequest"
DEEP_LINKING_RESPONSE = "LtiDeepLinkingResponse"

_LTI = "https://purl.imsglobal.org/spec/lti/claim/"
_DL = "https://purl.imsglobal.org/spec/lti-dl/claim/"
CLAIM = {
    "message_type": _LTI + "message_type",
    "version": _LTI + "version",
    "deployment_id": _LTI + "deployment_id",
    "target_link_uri": _LTI + "target_link_uri",
    "resource_link": _LTI + "resource_link",
    "roles": _LTI + "roles",
    "context": _LTI + "context",
    "custom": _LTI + "custom",
    "lis": _LTI + "lis",
    "ext": _LTI + "ext",
    "dl_settings": _DL + "deep_linking_settings",
    "dl_content_items": _DL + "content_items",
    "dl_data": _DL + "data",
    "nrps": "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice",
    "ags": "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint",
}
NRPS_SCOPE = "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly"
AGS_SCOPES = (
    "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem",
    "https://purl.imsglobal.org/spec/lti-ags/scope/score",
)

# Context and institution roles that make a teacher here (full URIs or LTI's short forms).
_TEACHING = frozenset({"Instructor", "Administrator"})


def lab_role(roles: Iterable[object]) -> Role:
    """The lab role of an LMS user: a teacher for Instructor/Administrator, else a student.

    Examples
    --------
    >>> lab_role(["http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"])
    <Role.TEACHER: 'teacher'>
    >>> lab_role(["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"])
    <Role.STUDENT: 'student'>
    >>> lab_role([])
    <Role.STUDENT: 'student'>
    """
    for role in roles:
        if not isinstance(role, str):
            continue
        name = role.rsplit("#", 1)[-1].rsplit("/", 1)[-1]
        # "membership/Instructor#TeachingAssistant" is a sub-role: its name is after '#'.
        if name in _TEACHING:
            return Role.TEACHER
    return Role.STUDENT


def course_role(roles: Iterable[object]) -> MemberRole:
    """The place of an LMS user in the lab course: teacher, teaching assistant or student.

    A teacher (:func:`lab_role`) teaches; else a ``TeachingAssistant`` (LTI's
    ``membership/Instructor#TeachingAssistant`` or the short name) assists,
    with a student's account; anyone else is a student.

    Examples
    --------
    >>> course_role(["http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant"])
    <MemberRole.ASSISTANT: 'assistant'>
    >>> course_role(["Instructor", "TeachingAssistant"])
    <MemberRole.TEACHER: 'teacher'>
    >>> course_role(["Learner"])
    <MemberRole.STUDENT: 'student'>
    """
    listed = list(roles)
    if lab_role(listed) is Role.TEACHER:
        return MemberRole.TEACHER
    for role in listed:
        if (
            isinstance(role, str)
            and role.rsplit("#", 1)[-1].rsplit("/", 1)[-1] == "TeachingAssistant"
        ):
            return MemberRole.ASSISTANT
    return MemberRole.STUDENT
