"""Who may do what on which object: the lab's one policy table (issue #25).

Every privileged action is an :class:`Action`; :data:`POLICY` says, for each
kind of actor (:class:`Actor`), how far it reaches (:class:`Scope`). Routes,
the command line and the live socket ask :func:`scope_of`; the check of a
course-scoped action against the database (is this teacher in that course?)
is :class:`thermolab.lab.classes.authorize.Authorizer`. The table is pure
data, so a test can print it and the route matrix
(``tests/lab/test_authorization_matrix.py``) can hold every route to it.

Actors
------
``admin``
    A lab administrator: a teacher with the ``admin`` flag. Reaches the whole
    lab: accounts, rigs, LTI platforms, the audit log, and every course.
``teacher``
    Acts in the courses they teach only (``course_members.role = teacher``);
    a course they create makes them its first teacher.
``assistant``
    A teaching assistant: a place in one course (``course_members.role =
    assistant``), not a kind of account — a student's or a teacher's account
    may assist a course. In the courses they assist (scope ``taught``) an
    assistant sees what the teacher sees: the roster, the assignments (drafts
    too), the hand-ins and grades, the analytics. They change nothing the
    course is made of: not its class list, enrolment code, rigs, settings,
    assignments or assistants, and no mark; nor anyone's password. Turns at a
    rig (extend, end) stay with teachers' accounts: a rig is shared by
    courses, an assistant's reach is one course.
``student``
    Their own account, their courses' assignments and bookings.

A user an LMS launched (LTI 1.3) is a ``teacher``, an ``assistant`` (LTI
``TeachingAssistant``, with a student's account) or a ``student`` of the
course the launch's context is linked to — never an administrator, whatever
roles the platform sends.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

from thermolab.errors import AccessDeniedError
from thermolab.lab.accounts.users import Principal

__all__ = [
    "POLICY",
    "Action",
    "Actor",
    "Scope",
    "actor_of",
    "assists",
    "member_reaches",
    "require_lab",
    "scope_of",
    "who_may",
]


class Actor(enum.StrEnum):
    """The kinds of people the policy tells apart."""

    ADMIN = "admin"
    TEACHER = "teacher"
    ASSISTANT = "assistant"  # of a course: never what actor_of answers
    STUDENT = "student"


class Scope(enum.StrEnum):
    """How far an actor reaches for an action.

    ``lab``: every object; ``taught``: the courses the actor teaches, or for
    an assistant assists (a person: a student of such a course); ``self``:
    the actor's own account; ``none``: refused.
    """

    LAB = "lab"
    TAUGHT = "taught"
    SELF = "self"
    NONE = "none"


class Action(enum.StrEnum):
    """A privileged action; the value is the words after "may" in a refusal."""

    ACCOUNTS_READ = "list accounts"
    ACCOUNT_CREATE = "create accounts"
    ACCOUNT_REMOVE = "remove accounts"
    ACCOUNT_FORGET = "remove people and their names from every record"
    ACCOUNT_ROLE = "make or unmake lab administrators"
    PASSWORD_SET = "set another person's password"
    PASSWORD_RESET = "reset a password"
    COURSES_READ = "list courses"
    COURSE_CREATE = "create courses"
    COURSE_READ = "see a course's roster"
    COURSE_ROSTER = "upload class lists"
    COURSE_ENROL_CODE = "change enrolment codes"
    COURSE_RIGS = "choose a course's rigs"
    COURSE_ANALYTICS = "see a course's analytics"
    COURSE_ASSIGNMENTS_EDIT = "set and edit a course's assignments"
    COURSE_HAND_INS = "see a course's hand-ins, grades and draft assignments"
    COURSE_ASSISTANTS = "add or remove a course's teaching assistants"
    COURSE_LMS_ROSTER = "synchronise a course's roster with its LMS"
    COURSE_LMS_GRADES = "see and retry a course's grades for its LMS"
    COURSE_CLOSE = "close a course at the end of its term"
    COURSE_REOPEN = "reopen a closed course"
    COURSE_COPY = "copy a course to the next term"
    COURSE_PURGE_STUDENTS = "remove a closed course's students"
    COURSE_MARK_OVERRIDE = "override a student's mark in a course"
    COURSE_EXTENSIONS = "extend a student's deadline in a course"
    COURSE_GROUPS = "form and remove a course's lab groups"
    RIG_SETTINGS_READ = "see a rig's settings"
    RIG_SETTINGS_EDIT = "change a rig's settings"
    RIG_SERVICE = "take rigs in or out of service"
    RIG_HOSTS = "see the rig hosts"
    LTI_PLATFORMS = "manage LTI platforms and keys"
    AUDIT_READ = "read the audit log"
    BOOKING_SERIES = "book a course's weekly series of slots"
    BOOKING_QUOTA = "set how long a course's students may book for themselves"
    BOOKING_OWN = "book a free slot for themselves within their course's quota"
    CALENDAR_FEED = "subscribe a calendar application to their bookings"
    BOOKING_REMINDERS = "have booking reminders sent by e-mail"


_A, _T, _S, _N = Scope.LAB, Scope.TAUGHT, Scope.SELF, Scope.NONE

# action: (admin, teacher, assistant, student)
_TABLE: dict[Action, tuple[Scope, Scope, Scope, Scope]] = {
    Action.ACCOUNTS_READ: (_A, _N, _N, _N),
    Action.ACCOUNT_CREATE: (_A, _N, _N, _N),
    Action.ACCOUNT_REMOVE: (_A, _N, _N, _N),
    Action.ACCOUNT_FORGET: (_A, _N, _N, _N),  # a person may be in several courses
    Action.ACCOUNT_ROLE: (_A, _N, _N, _N),
    Action.PASSWORD_SET: (_A, _T, _N, _S),
    Action.PASSWORD_RESET: (_A, _T, _N, _N),
    Action.COURSES_READ: (_A, _T, _T, _N),
    Action.COURSE_CREATE: (_A, _A, _N, _N),
    Action.COURSE_READ: (_A, _T, _T, _N),
    Action.COURSE_ROSTER: (_A, _T, _N, _N),
    Action.COURSE_ENROL_CODE: (_A, _T, _N, _N),
    Action.COURSE_RIGS: (_A, _T, _N, _N),
    Action.COURSE_ANALYTICS: (_A, _T, _T, _N),
    Action.COURSE_ASSIGNMENTS_EDIT: (_A, _T, _N, _N),
    Action.COURSE_HAND_INS: (_A, _T, _T, _N),
    Action.COURSE_ASSISTANTS: (_A, _T, _N, _N),
    Action.COURSE_LMS_ROSTER: (_A, _T, _N, _N),
    Action.COURSE_LMS_GRADES: (_A, _T, _N, _N),
    Action.COURSE_CLOSE: (_A, _T, _N, _N),
    Action.COURSE_REOPEN: (_A, _N, _N, _N),  # a closed term's marks are settled
    Action.COURSE_COPY: (_A, _T, _N, _N),
    Action.COURSE_PURGE_STUDENTS: (_A, _N, _N, _N),  # removing people is ACCOUNT_FORGET's
    # A teacher's grading tools; assistants read them (COURSE_HAND_INS), change none.
    Action.COURSE_MARK_OVERRIDE: (_A, _T, _N, _N),
    Action.COURSE_EXTENSIONS: (_A, _T, _N, _N),
    Action.COURSE_GROUPS: (_A, _T, _N, _N),
    Action.RIG_SETTINGS_READ: (_A, _A, _N, _N),
    Action.RIG_SETTINGS_EDIT: (_A, _N, _N, _N),
    Action.RIG_SERVICE: (_A, _A, _N, _N),
    Action.RIG_HOSTS: (_A, _A, _N, _N),
    Action.LTI_PLATFORMS: (_A, _N, _N, _N),
    Action.AUDIT_READ: (_A, _N, _N, _N),
    Action.BOOKING_SERIES: (_A, _T, _N, _N),
    Action.BOOKING_QUOTA: (_A, _T, _N, _N),
    # A student's own: in a course they are a student of, on its rigs, within its quota.
    Action.BOOKING_OWN: (_N, _N, _N, _S),
    # One's own feed and address; a course's feed needs a place in the course.
    Action.CALENDAR_FEED: (_S, _S, _N, _S),
    Action.BOOKING_REMINDERS: (_S, _S, _N, _S),
}

POLICY: Mapping[Action, Mapping[Actor, Scope]] = MappingProxyType(
    {
        action: MappingProxyType(dict(zip(Actor, scopes, strict=True)))
        for action, scopes in _TABLE.items()
    }
)
"""For each action, each actor's reach; every :class:`Action` is a key."""


def actor_of(who: Principal) -> Actor:
    """Return the kind of actor ``who``'s account is (an assistant is one in a course only)."""
    if who.is_admin:
        return Actor.ADMIN
    return Actor.TEACHER if who.is_teacher else Actor.STUDENT


def scope_of(who: Principal, action: Action) -> Scope:
    """Return how far ``who`` reaches for ``action``.

    Examples
    --------
    >>> from thermolab.lab.db.models import Role
    >>> tina = Principal(1, "tina", Role.TEACHER)
    >>> scope_of(tina, Action.COURSE_ROSTER)
    <Scope.TAUGHT: 'taught'>
    >>> scope_of(tina, Action.ACCOUNT_CREATE)
    <Scope.NONE: 'none'>
    """
    return POLICY[action][actor_of(who)]


def assists(action: Action) -> bool:
    """Whether a course's teaching assistants may ``action`` in it.

    Examples
    --------
    >>> assists(Action.COURSE_HAND_INS), assists(Action.COURSE_ROSTER)
    (True, False)
    """
    return POLICY[action][Actor.ASSISTANT] is Scope.TAUGHT


def member_reaches(who: Principal, action: Action, held: str | None) -> bool:
    """Whether ``who``, holding the place ``held`` in a course (``None``: not in it), may
    ``action`` there. A lab-wide reach is :func:`scope_of`'s.

    Examples
    --------
    >>> from thermolab.lab.db.models import Role
    >>> tara = Principal(2, "tara", Role.STUDENT)
    >>> member_reaches(tara, Action.COURSE_HAND_INS, "assistant")
    True
    >>> member_reaches(tara, Action.COURSE_ROSTER, "assistant")
    False
    """
    if held == Actor.TEACHER.value:
        return scope_of(who, action) in (Scope.LAB, Scope.TAUGHT)
    if held == Actor.ASSISTANT.value:
        return assists(action)
    return False


def who_may(action: Action, scopes: tuple[Scope, ...] = (Scope.LAB,)) -> str:
    """The actors reaching ``action`` with one of ``scopes``, for a refusal.

    Examples
    --------
    >>> who_may(Action.COURSE_READ, (Scope.LAB, Scope.TAUGHT))
    'a lab administrator or a teacher or a teaching assistant'
    """
    names = [_NAMES[a] for a, scope in POLICY[action].items() if scope in scopes]
    return " or ".join(names)


_NAMES = {
    Actor.ADMIN: "a lab administrator",
    Actor.TEACHER: "a teacher",
    Actor.ASSISTANT: "a teaching assistant",
    Actor.STUDENT: "a student",
}


def require_lab(who: Principal, action: Action) -> None:
    """Refuse ``action`` unless ``who`` reaches it lab-wide (no course to check).

    Raises
    ------
    AccessDeniedError
        Saying who may.
    """
    if scope_of(who, action) is not Scope.LAB:
        raise AccessDeniedError(f"only {who_may(action)} may {action}")
