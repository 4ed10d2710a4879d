"""Who a launch signs in, and into which course.

* **The account.** An LMS user is known by (platform, ``sub``)
  (:class:`~thermolab.lab.db.lti_models.LtiIdentity`). On their first launch
  the lab looks for an account made before under the login name the LMS
  gives (``lis.person_sourcedid``, or Moodle's ``ext.user_username``),
  normalised like every login name: an account of that name *and the same
  role* is linked, never copied. A teacher's account is never linked to an
  LMS learner (nor a student's to an instructor): a new account is made
  instead. A new account takes that name if it is free, else
  ``lti-<12 hex digits of the identity's hash>``; its password is random and
  unknown (the person signs in through the LMS; a teacher can reset it).
* **The role.** Instructor or Administrator is a teacher, anything else a
  student (:func:`~thermolab.lab.lti.claims.lab_role`); in the course, a
  TeachingAssistant is an assistant (:func:`~thermolab.lab.lti.claims.course_role`).
* **The course.** An LMS context (platform, context id) fills one lab course
  (:class:`~thermolab.lab.db.lti_models.LtiContext`), made on the first
  launch from the context's label and title; the user joins it.
"""

from __future__ import annotations

import hashlib
import re
import secrets
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from argon2 import PasswordHasher
from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import InvalidParameterError
from thermolab.lab.accounts.names import normalize_display_name, normalize_username
from thermolab.lab.classes.course_names import new_enrol_code
from thermolab.lab.db.lti_models import URL_LENGTH, LtiContext, LtiIdentity, LtiResourceLink
from thermolab.lab.db.models import Course, CourseMember, MemberRole, Role, User
from thermolab.lab.lti.claims import CLAIM, course_role, lab_role

__all__ = [
    "LmsPerson",
    "add_member",
    "join_course",
    "person_of",
    "remember_link",
    "sign_in_account",
]


@dataclass(frozen=True, slots=True)
class LmsPerson:
    """An LMS user as a launch or a roster describes them."""

    sub: str
    role: Role
    login_name: str | None
    display_name: str | None
    course_role: MemberRole = MemberRole.STUDENT


def person_of(claims: dict[str, Any]) -> LmsPerson:
    """The person of a launch's claims (or of an NRPS member, which uses the same names)."""
    lis = claims.get(CLAIM["lis"]) or {}
    ext = claims.get(CLAIM["ext"]) or {}
    login = (
        (lis.get("person_sourcedid") if isinstance(lis, dict) else None)
        or (ext.get("user_username") if isinstance(ext, dict) else None)
        or claims.get("lis_person_sourcedid")
        or claims.get("ext_user_username")
    )
    name = claims.get("name") or " ".join(
        str(p) for p in (claims.get("given_name"), claims.get("family_name")) if p
    )
    roles = claims.get(CLAIM["roles"], claims.get("roles", []))
    listed = roles if isinstance(roles, list) else []
    return LmsPerson(
        sub=str(claims.get("sub") or claims.get("user_id") or ""),
        role=lab_role(listed),
        login_name=str(login) if login else None,
        display_name=str(name) if name else None,
        course_role=course_role(listed),
    )


def _username(text: str | None) -> str | None:
    if not text:
        return None
    try:
        return normalize_username(text)
    except InvalidParameterError:
        return None


def _display(text: str | None) -> str | None:
    if not text:
        return None
    try:
        return normalize_display_name(text)
    except InvalidParameterError:
        return None


def sign_in_account(
    session: Session, platform_id: int, person: LmsPerson, now: datetime, hasher: PasswordHasher
) -> User:
    """The account of ``person``: linked before, made before under their name, or new."""
    linked = session.scalar(
        select(User)
        .join(LtiIdentity, LtiIdentity.user_id == User.id)
        .where(LtiIdentity.platform_id == platform_id, LtiIdentity.sub == person.sub)
    )
    if linked is not None:
        return linked
    name = _username(person.login_name)
    user = None
    if name is not None:
        user = session.scalar(select(User).where(User.username == name))
        if user is not None and user.role != person.role.value:
            user, name = None, None  # never link across roles
    if user is None:
        digest = hashlib.sha256(f"{platform_id}\n{person.sub}".encode()).hexdigest()[:12]
        if name is None or session.scalar(select(User.id).where(User.username == name)):
            name = f"lti-{digest}"
        user = User(
            username=name,
            display_name=_display(person.display_name),
            role=person.role.value,
            password_hash=hasher.hash(secrets.token_urlsafe(32)),
            created_at=now,
            password_changed_at=now,
            must_change_password=False,
        )
        session.add(user)
        session.flush()
    session.add(LtiIdentity(platform_id=platform_id, sub=person.sub, user_id=user.id))
    session.flush()
    return user


_SLUG = re.compile(r"[^a-z0-9._-]+")


def _printable(text: str) -> str:
    """``text`` without control characters (PostgreSQL refuses NUL in text)."""
    return "".join(c if c.isprintable() else " " for c in text)


def join_course(
    session: Session,
    platform_id: int,
    context: dict[str, Any],
    services: dict[str, str | None],
    now: datetime,
) -> Course:
    """The lab course of an LMS context (made on its first launch), with its service URLs."""
    context_id = _printable(str(context["id"]))[:255]
    found = session.scalar(
        select(LtiContext).where(
            LtiContext.platform_id == platform_id, LtiContext.context_id == context_id
        )
    )
    if found is not None:
        for name, url in services.items():
            if url:
                setattr(found, name, url)
        course = session.get(Course, found.course_id)
        if course is not None:
            return course
    label = _printable(str(context.get("label") or context.get("title") or "course"))
    slug = _SLUG.sub("-", label.casefold()).strip("-._")[:40] or "course"
    title = " ".join(_printable(str(context.get("title") or label)).split())[:200] or slug
    while True:
        name = f"lti-{slug}-{secrets.token_hex(3)}"
        if session.scalar(select(Course.id).where(Course.name == name)) is None:
            break
    course = Course(name=name, title=title, enrol_code=new_enrol_code(), created_at=now)
    session.add(course)
    session.flush()
    if found is not None:
        found.course_id = course.id
    else:
        session.add(
            LtiContext(
                platform_id=platform_id,
                context_id=context_id,
                course_id=course.id,
                memberships_url=services.get("memberships_url"),
                lineitems_url=services.get("lineitems_url"),
            )
        )
    session.flush()
    return course


def add_member(
    session: Session, course_id: int, user: User, role: MemberRole, now: datetime
) -> None:
    """Put ``user`` in the course (once) with ``role``; a closed course takes nobody new.

    A launch into a closed course still signs its members in (they read it).
    """
    course = session.get(Course, course_id)
    if course is not None and course.closed_at is not None:
        return
    member = session.scalar(
        select(CourseMember).where(
            CourseMember.course_id == course_id, CourseMember.user_id == user.id
        )
    )
    if member is None:
        session.add(
            CourseMember(course_id=course_id, user_id=user.id, role=role.value, joined_at=now)
        )
    elif member.role != role.value:
        member.role = role.value


def remember_link(session: Session, platform_id: int, claims: dict[str, Any]) -> None:
    """Keep a resource link's target and AGS line item (the column its grades go to)."""
    link = claims.get(CLAIM["resource_link"])
    if not isinstance(link, dict) or not link.get("id"):
        return
    custom = claims.get(CLAIM["custom"]) or {}
    target = custom.get("thermolab_target") if isinstance(custom, dict) else None
    ags = claims.get(CLAIM["ags"]) or {}
    lineitem = ags.get("lineitem") if isinstance(ags, dict) else None
    link_id = _printable(str(link["id"]))[:255]
    row = session.scalar(
        select(LtiResourceLink).where(
            LtiResourceLink.platform_id == platform_id, LtiResourceLink.link_id == link_id
        )
    )
    if row is None:
        row = LtiResourceLink(platform_id=platform_id, link_id=link_id)
        session.add(row)
    row.target = _printable(str(target))[:255] if target else None
    if isinstance(lineitem, str) and len(lineitem) <= URL_LENGTH and lineitem.isprintable():
        row.lineitem_url = lineitem
