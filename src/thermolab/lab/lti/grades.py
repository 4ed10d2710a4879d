"""The grade outbox (AGS): scores queued in the database, posted, retried, shown.

:meth:`GradeOutbox.queue_grade` is what "an assignment was marked" calls: it
only writes a row (in the caller's moment, never waiting on the network).
:meth:`GradeOutbox.deliver_due` posts the rows that are due — the lab's sweep
calls it — and on a failure waits longer each time (30 s, 1 min, 2 min, ...
capped at 1 hour) until ``max_attempts``, after which the row is ``failed``
and stays in the teacher's list with its last error. A mark changed later is
queued again: the newest score wins in the LMS (AGS keeps the latest).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Collection
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import Select, select

from thermolab.errors import InvalidParameterError, NotFoundError
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import (
    GradeStatus,
    LtiGrade,
    LtiIdentity,
    LtiPlatform,
    LtiResourceLink,
)
from thermolab.lab.db.models import Course, CourseMember
from thermolab.lab.lti.claims import AGS_SCOPES
from thermolab.lab.lti.errors import LtiError
from thermolab.lab.lti.platforms import PlatformInfo, check_url
from thermolab.lab.lti.services import PlatformClient

__all__ = ["GradeInfo", "GradeOutbox", "retry_delay"]

log = logging.getLogger(__name__)

MAX_ATTEMPTS = 8
_FIRST_RETRY = 30.0
_LONGEST_RETRY = 3600.0


def retry_delay(attempts: int) -> float:
    """Seconds before the next try after ``attempts`` failed ones.

    Examples
    --------
    >>> [retry_delay(n) for n in (1, 2, 3, 10)]
    [30.0, 60.0, 120.0, 3600.0]
    """
    return min(_FIRST_RETRY * 2.0 ** min(attempts - 1, 20), _LONGEST_RETRY)


@dataclass(frozen=True, slots=True)
class GradeInfo:
    """A queued score as the teacher's list shows it."""

    id: int
    platform: str
    lineitem_url: str
    sub: str
    score_given: float
    score_maximum: float
    timestamp: datetime
    status: GradeStatus
    attempts: int
    next_attempt_at: datetime
    last_error: str | None
    sent_at: datetime | None

    @classmethod
    def of(cls, row: LtiGrade, issuer: str) -> GradeInfo:
        """The info of a row."""
        return cls(
            row.id,
            issuer,
            row.lineitem_url,
            row.sub,
            row.score_given,
            row.score_maximum,
            row.timestamp,
            GradeStatus(row.status),
            row.attempts,
            row.next_attempt_at,
            row.last_error,
            row.sent_at,
        )


class GradeOutbox:
    """Queue scores for platforms' gradebooks and deliver them."""

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        client: PlatformClient,
        *,
        max_attempts: int = MAX_ATTEMPTS,
    ) -> None:
        self._db = db
        self._clock = clock
        self._client = client
        self._max = max_attempts
        self._lock = threading.Lock()

    def queue_grade(
        self,
        *,
        platform_id: int,
        lineitem_url: str,
        sub: str,
        score_given: float,
        score_maximum: float,
        timestamp: datetime | None = None,
        comment: str | None = None,
    ) -> int:
        """Queue a score for the LMS's line item; return the row's id (posted by the sweep).

        Raises
        ------
        InvalidParameterError
            A score that is not a finite number in [0, maximum], a maximum not > 0.
        NotFoundError
            An unknown platform.
        """
        if not (math.isfinite(score_maximum) and score_maximum > 0):
            raise InvalidParameterError("the score maximum must be a finite number above 0")
        if not (math.isfinite(score_given) and 0 <= score_given <= score_maximum):
            raise InvalidParameterError(
                f"the score must be a finite number from 0 to {score_maximum}"
            )
        if not 0 < len(sub) <= 255:
            raise InvalidParameterError("the LMS user id (sub) must have 1 to 255 characters")
        url = check_url(lineitem_url, "line item URL")
        now = self._clock.now()
        with self._db.write() as session:
            if session.get(LtiPlatform, platform_id) is None:
                raise NotFoundError(f"no LTI platform number {platform_id}")
            row = LtiGrade(
                platform_id=platform_id,
                lineitem_url=url,
                sub=sub,
                score_given=float(score_given),
                score_maximum=float(score_maximum),
                comment=comment,
                timestamp=timestamp or now,
                status=GradeStatus.PENDING.value,
                attempts=0,
                next_attempt_at=now,
            )
            session.add(row)
            session.flush()
            return row.id

    def queue_for_user(
        self,
        *,
        user_id: int,
        target: str,
        score_given: float,
        score_maximum: float,
        timestamp: datetime | None = None,
        comment: str | None = None,
    ) -> list[int]:
        """Queue a lab user's mark for every LMS activity that links ``target``.

        The user's LMS identities (platform, ``sub``) meet the resource links
        of those platforms whose target is ``target`` (``assignment:<id>``...)
        and that have a line item; a user or target the LMS never launched
        queues nothing. Returns the rows' ids.
        """
        with self._db.read() as session:
            pairs = session.execute(
                select(LtiIdentity.platform_id, LtiIdentity.sub, LtiResourceLink.lineitem_url)
                .join(
                    LtiResourceLink,
                    LtiResourceLink.platform_id == LtiIdentity.platform_id,
                )
                .where(
                    LtiIdentity.user_id == user_id,
                    LtiResourceLink.target == target,
                    LtiResourceLink.lineitem_url.is_not(None),
                )
                .order_by(LtiResourceLink.id)
            ).all()
        return [
            self.queue_grade(
                platform_id=platform_id,
                lineitem_url=str(url),
                sub=sub,
                score_given=score_given,
                score_maximum=score_maximum,
                timestamp=timestamp,
                comment=comment,
            )
            for platform_id, sub, url in pairs
        ]

    def list(self, *, limit: int = 200, courses: Collection[str] | None = None) -> list[GradeInfo]:
        """The newest queued scores first (failed and pending ones are what a teacher checks).

        ``courses``: only the scores of students of these lab courses (``None``: all).
        """
        query = (
            select(LtiGrade, LtiPlatform.issuer)
            .join(LtiPlatform, LtiPlatform.id == LtiGrade.platform_id)
            .order_by(LtiGrade.id.desc())
            .limit(limit)
        )
        if courses is not None:
            query = query.where(LtiGrade.id.in_(_grades_of(courses)))
        with self._db.read() as session:
            rows = session.execute(query).all()
            return [GradeInfo.of(row, issuer) for row, issuer in rows]

    def retry(self, grade_id: int, *, courses: Collection[str] | None = None) -> GradeInfo:
        """Make a failed (or pending) score due now, with a fresh count of attempts.

        ``courses``: refuse (as unknown) a score of a student of none of these courses.
        """
        now = self._clock.now()
        with self._db.write() as session:
            row = session.get(LtiGrade, grade_id)
            if row is not None and courses is not None:
                visible = session.scalar(
                    select(LtiGrade.id).where(
                        LtiGrade.id == grade_id, LtiGrade.id.in_(_grades_of(courses))
                    )
                )
                row = row if visible is not None else None
            if row is None:
                raise NotFoundError(f"no queued grade number {grade_id}")
            if row.status != GradeStatus.SENT.value:
                row.status = GradeStatus.PENDING.value
                row.attempts = 0
                row.next_attempt_at = now
            issuer = session.get(LtiPlatform, row.platform_id)
            return GradeInfo.of(row, issuer.issuer if issuer else "")

    def deliver_due(self, *, limit: int = 20) -> int:
        """Post the scores that are due; return how many were posted."""
        if not self._lock.acquire(blocking=False):
            return 0  # another thread is delivering
        try:
            return self._deliver(limit)
        finally:
            self._lock.release()

    def _deliver(self, limit: int) -> int:
        now = self._clock.now()
        with self._db.read() as session:
            due = session.execute(
                select(LtiGrade, LtiPlatform)
                .join(LtiPlatform, LtiPlatform.id == LtiGrade.platform_id)
                .where(
                    LtiGrade.status == GradeStatus.PENDING.value,
                    LtiGrade.next_attempt_at <= now,
                )
                .order_by(LtiGrade.id)
                .limit(limit)
            ).all()
            work = [
                (
                    row.id,
                    PlatformInfo.of(platform),
                    row.lineitem_url,
                    {
                        "userId": row.sub,
                        "scoreGiven": row.score_given,
                        "scoreMaximum": row.score_maximum,
                        "activityProgress": "Completed",
                        "gradingProgress": "FullyGraded",
                        "timestamp": _iso(row.timestamp),
                        **({"comment": row.comment} if row.comment else {}),
                    },
                )
                for row, platform in due
            ]
        sent = 0
        for grade_id, platform, url, score in work:
            error: str | None = None
            try:
                self._client.post_score(platform, url, score, AGS_SCOPES)
            except LtiError as exc:
                error = str(exc)
                log.warning("LTI grade %d to %s not posted: %s", grade_id, platform.issuer, error)
            self._record(grade_id, error)
            sent += error is None
        return sent

    def _record(self, grade_id: int, error: str | None) -> None:
        now = self._clock.now()
        with self._db.write() as session:
            row = session.get(LtiGrade, grade_id)
            if row is None:
                return
            row.attempts += 1
            row.last_error = error
            if error is None:
                row.status = GradeStatus.SENT.value
                row.sent_at = now
            elif row.attempts >= self._max:
                row.status = GradeStatus.FAILED.value
            else:
                row.next_attempt_at = now + timedelta(seconds=retry_delay(row.attempts))


def _iso(moment: datetime) -> str:
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _grades_of(courses: Collection[str]) -> Select[int]:
    """The ids of the scores whose LMS user is a lab account in one of ``courses``."""
    return (
        select(LtiGrade.id)
        .join(
            LtiIdentity,
            (LtiIdentity.platform_id == LtiGrade.platform_id) & (LtiIdentity.sub == LtiGrade.sub),
        )
        .join(CourseMember, CourseMember.user_id == LtiIdentity.user_id)
        .join(Course, Course.id == CourseMember.course_id)
        .where(Course.name.in_(list(courses)))
    )
