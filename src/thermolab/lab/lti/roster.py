"""Names and Role Provisioning Services: the LMS course's roster into the lab course.

:meth:`RosterSync.sync` reads every page of the context's membership URL
(saved from the course's launches) and, in one transaction, makes or links
each active member's account exactly as a launch would (:mod:`.accounts`: no
duplicates of accounts made before) and puts them in the course; members who
came from this LMS and are no longer listed, or are listed as ``Inactive`` or
``Deleted``, leave the course (their accounts and runs stay). People added by
a class list or an enrolment code are not touched.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from argon2 import PasswordHasher
from sqlalchemy import delete, select

from thermolab.errors import NotFoundError
from thermolab.lab.classes.closed import require_open
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import LtiContext, LtiIdentity, LtiPlatform
from thermolab.lab.db.models import Course, CourseMember, User
from thermolab.lab.lti.accounts import add_member, person_of, sign_in_account
from thermolab.lab.lti.claims import NRPS_SCOPE
from thermolab.lab.lti.platforms import PlatformInfo
from thermolab.lab.lti.services import PlatformClient

__all__ = ["RosterReport", "RosterSync"]


@dataclass(slots=True)
class RosterReport:
    """What a roster sync changed: login names added to and removed from the course."""

    added: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    kept: int = 0


class RosterSync:
    """Synchronise lab courses with their LMS contexts."""

    def __init__(
        self, db: Database, clock: LabClock, hasher: PasswordHasher, client: PlatformClient
    ) -> None:
        self._db = db
        self._clock = clock
        self._hasher = hasher
        self._client = client

    def sync(self, course_name: str) -> RosterReport:
        """Bring the course's roster in line with its LMS context's.

        Raises
        ------
        NotFoundError
            The course does not exist or was not made by an LTI launch with a roster service.
        LtiServiceError
            The platform could not be reached or answered nonsense (nothing changed).
        """
        with self._db.read() as session:
            found = session.execute(
                select(LtiContext, LtiPlatform, Course)
                .join(Course, Course.id == LtiContext.course_id)
                .join(LtiPlatform, LtiPlatform.id == LtiContext.platform_id)
                .where(Course.name == course_name.strip().lower())
            ).first()
            if found is None or not found[0].memberships_url:
                raise NotFoundError(
                    f"course {course_name!r} has no LMS roster (launch it from the LMS first)"
                )
            context, platform_row, course = found
            require_open(course, "synchronise its roster")
            course_id, url = context.course_id, str(context.memberships_url)
            platform = PlatformInfo.of(platform_row)
        members = self._client.memberships(platform, url, NRPS_SCOPE)
        listed_people = [
            person_of(m) for m in members if str(m.get("status", "Active")) == "Active"
        ]
        # A member without a usable id cannot be matched to a launch: left out.
        active = [p for p in listed_people if 0 < len(p.sub) <= 255 and p.sub.isprintable()]
        report = RosterReport()
        now = self._clock.now()
        with self._db.write() as session:
            closing = session.get(Course, course_id)
            if closing is not None:  # closed while the LMS was asked
                require_open(closing, "synchronise its roster")
            before = set(
                session.scalars(
                    select(CourseMember.user_id).where(CourseMember.course_id == course_id)
                )
            )
            listed: set[int] = set()
            for person in active:
                user = sign_in_account(session, platform.id, person, now, self._hasher)
                add_member(session, course_id, user, person.course_role, now)
                listed.add(user.id)
                if user.id in before:
                    report.kept += 1
                else:
                    report.added.append(user.username)
            from_lms = set(
                session.scalars(
                    select(LtiIdentity.user_id).where(LtiIdentity.platform_id == platform.id)
                )
            )
            gone = sorted((before & from_lms) - listed)
            if gone:
                report.removed = list(
                    session.scalars(select(User.username).where(User.id.in_(gone)))
                )
                session.execute(
                    delete(CourseMember).where(
                        CourseMember.course_id == course_id, CourseMember.user_id.in_(gone)
                    )
                )
        report.added.sort()
        report.removed.sort()
        return report
