"""Booking reminders by e-mail, where the lab has a mail server (``[smtp]``).

A person gives an address and how many minutes before a booking they want a
reminder (opt-in: the lab has no one's address otherwise). The lab's sweep
calls :meth:`ReminderService.send_due` about every half minute: for each
booking of one of their courses (a student's: not a classmate's own booking)
whose start is at most that many minutes away and not yet reached, one
plain-text message, its times in the lab's ``time_zone`` with the zone named
(``02/03/2026, 14:00–15:00 (America/Sao_Paulo)``) and its words in the
language the person subscribed in. Each is recorded in ``reminders_sent`` *before* it is
sent, under a unique (booking, person) key, so a restart, a second worker or
an overlapping sweep never sends it twice; a message the server then refuses
is logged and not retried (a late reminder is worse than none).

Sent with the standard library's ``smtplib`` and ``email``.
"""

from __future__ import annotations

import logging
import os
import smtplib
import threading
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from email.message import EmailMessage
from email.utils import formataddr

from sqlalchemy import or_, select
from sqlalchemy.exc import IntegrityError

from thermolab.errors import AccessDeniedError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.policy import Action, Scope, scope_of, who_may
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config.smtp import SmtpConfig
from thermolab.lab.config.time_zones import zone_named
from thermolab.lab.db import Database
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.booking_tool_models import ReminderAddress, ReminderSent
from thermolab.lab.db.models import Course, CourseMember
from thermolab.lab.error_messages import DEFAULT_LANGUAGE, LANGUAGES, translate

__all__ = [
    "MAX_MINUTES_BEFORE",
    "REMINDER_WORDS",
    "ReminderService",
    "ReminderSettings",
    "slot_words",
]

log = logging.getLogger(__name__)

MAX_MINUTES_BEFORE = 7 * 24 * 60
"""The earliest reminder: a week before."""
_INTERVAL = timedelta(seconds=30)

_SUBJECT = "Reminder: {course}, {start}"
_BODY = "A booking of {course} on {rigs}: {when}."
_FOOTER = (
    "The calendar page of {lab} shows it in your time zone; you change or stop these "
    "reminders there."
)
REMINDER_WORDS = (_SUBJECT, _BODY, _FOOTER)
"""The reminder's sentences (msgids of the server's catalogues, in the reader's language)."""


@dataclass(frozen=True, slots=True)
class ReminderSettings:
    """Where and when a person's reminders go; ``available``: the lab has a mail server."""

    available: bool
    email: str | None
    minutes_before: int | None


def _check_email(email: str) -> str:
    email = email.strip()
    local, at, domain = email.rpartition("@")
    if not at or not local or "." not in domain or any(c.isspace() for c in email):
        raise InvalidParameterError(f"not an e-mail address: {email!r}")
    if len(email) > 254:
        raise InvalidParameterError("an e-mail address has at most 254 characters")
    return email


def slot_words(start: datetime, end: datetime, zone: str, language: str) -> str:
    """A slot's day and times in ``zone``, the zone named, dates as ``language`` writes them.

    >>> a = datetime(2026, 3, 2, 17, tzinfo=UTC)
    >>> slot_words(a, a + timedelta(hours=1), "America/Sao_Paulo", "pt-BR")
    '02/03/2026, 14:00–15:00 (America/Sao_Paulo)'
    >>> slot_words(a, a + timedelta(days=1), "UTC", "en")
    '2026-03-02 17:00 – 2026-03-03 17:00 (UTC)'
    """
    tz = zone_named(zone)
    # SQLite gives the stored UTC instants back without their zone.
    a, b = (t.replace(tzinfo=UTC) if t.tzinfo is None else t for t in (start, end))
    a, b = a.astimezone(tz), b.astimezone(tz)
    day = "%Y-%m-%d" if language == "en" else "%d/%m/%Y"
    if a.date() == b.date():
        return f"{a.strftime(day)}, {a:%H:%M}–{b:%H:%M} ({zone})"
    return f"{a.strftime(day)} {a:%H:%M} – {b.strftime(day)} {b:%H:%M} ({zone})"


class ReminderService:
    """People's reminder addresses; the sending of due reminders.

    ``time_zone`` is the lab's (an IANA name): the reminders state their times in it.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        smtp: SmtpConfig | None,
        lab_title: str,
        time_zone: str = "UTC",
    ) -> None:
        self._db = db
        self._clock = clock
        self._smtp = smtp
        self._title = lab_title
        self._zone = time_zone
        self._running = threading.Lock()
        self._last: datetime | None = None

    def settings(self, who: Principal) -> ReminderSettings:
        """``who``'s address and lead time (none set: ``None``)."""
        _require(who)
        with self._db.read() as session:
            row = session.get(ReminderAddress, who.user_id)
            return ReminderSettings(
                self._smtp is not None,
                None if row is None else row.email,
                None if row is None else row.minutes_before,
            )

    def subscribe(
        self, who: Principal, email: str, minutes_before: int, language: str = "en"
    ) -> ReminderSettings:
        """Send ``who`` a reminder ``minutes_before`` each of their bookings, to ``email``,
        written in ``language`` (one of :data:`~thermolab.lab.error_messages.LANGUAGES`).

        Raises
        ------
        InvalidParameterError
            Not an address; a lead time outside 1 to :data:`MAX_MINUTES_BEFORE`;
            a lab with no mail server (nothing could be sent).
        """
        _require(who)
        if self._smtp is None:
            raise InvalidParameterError(
                "this lab has no mail server ([smtp] in its configuration), so it sends no "
                "reminders"
            )
        if not 1 <= minutes_before <= MAX_MINUTES_BEFORE:
            raise InvalidParameterError(
                f"a reminder comes 1 to {MAX_MINUTES_BEFORE} minutes before, got {minutes_before}"
            )
        email = _check_email(email)
        with self._db.write() as session:
            row = session.get(ReminderAddress, who.user_id)
            if row is None:
                row = ReminderAddress(user_id=who.user_id)
                session.add(row)
            row.email = email
            row.minutes_before = minutes_before
            row.language = language if language in LANGUAGES else DEFAULT_LANGUAGE
        return ReminderSettings(True, email, minutes_before)

    def unsubscribe(self, who: Principal) -> None:
        """Stop ``who``'s reminders and forget their address.

        Raises
        ------
        NotFoundError
            No address was set.
        """
        _require(who)
        with self._db.write() as session:
            row = session.get(ReminderAddress, who.user_id)
            if row is None:
                raise NotFoundError("you have no reminder address")
            session.delete(row)

    def kick(self) -> None:
        """Send due reminders in a thread of its own, at most every 30 s (the sweep's call)."""
        now = self._clock.now()
        if self._smtp is None or (self._last is not None and now - self._last < _INTERVAL):
            return
        self._last = now
        threading.Thread(target=self._send_quietly, daemon=True).start()

    def _send_quietly(self) -> None:
        try:
            self.send_due()
        except Exception:  # a database hiccup: the next sweep tries again
            log.exception("booking reminders failed")

    def send_due(self) -> int:
        """Send the reminders due now; return how many were sent (0 without ``[smtp]``)."""
        if self._smtp is None or not self._running.acquire(blocking=False):
            return 0
        try:
            sent = 0
            for key, message in self._claim_due():
                if self._send(message):
                    sent += 1
                else:
                    log.warning("booking reminder %s not sent", key)
            return sent
        finally:
            self._running.release()

    def _claim_due(self) -> list[tuple[tuple[int, int], EmailMessage]]:
        now = self._clock.now()
        due: list[tuple[tuple[int, int], EmailMessage]] = []
        with self._db.read() as session:
            rows = session.execute(
                select(Booking, Course, ReminderAddress)
                .join(Course, Course.id == Booking.course_id)
                .join(CourseMember, CourseMember.course_id == Booking.course_id)
                .join(ReminderAddress, ReminderAddress.user_id == CourseMember.user_id)
                .where(
                    Booking.starts_at > now,
                    Booking.starts_at <= now + timedelta(minutes=MAX_MINUTES_BEFORE),
                    or_(
                        Booking.booked_for.is_(None),
                        Booking.booked_for == CourseMember.user_id,
                        CourseMember.role != "student",
                    ),
                )
                .order_by(Booking.starts_at)
            ).all()
            already = {
                (booking_id, user_id)
                for booking_id, user_id in session.execute(
                    select(ReminderSent.booking_id, ReminderSent.user_id).where(
                        ReminderSent.booking_id.in_({b.id for b, _, _ in rows})
                    )
                )
            }
            for booking, course, address in rows:
                key = (booking.id, address.user_id)
                lead = timedelta(minutes=address.minutes_before)
                if key in already or booking.starts_at - lead > now:
                    continue
                rigs = sorted(
                    session.scalars(
                        select(BookingRig.rig_id).where(BookingRig.booking_id == booking.id)
                    )
                )
                due.append((key, self._message(address, booking, course, rigs)))
        claimed = []
        for key, message in due:
            try:
                with self._db.write() as session:
                    session.add(ReminderSent(booking_id=key[0], user_id=key[1], sent_at=now))
            except IntegrityError:
                continue  # another worker (or an earlier sweep) has it
            claimed.append((key, message))
        return claimed

    def _message(
        self, to: ReminderAddress, booking: Booking, course: Course, rigs: list[str]
    ) -> EmailMessage:
        assert self._smtp is not None

        def say(sentence: str, **params: str) -> str:
            return translate(sentence, to.language).format(**params)

        when = slot_words(booking.starts_at, booking.ends_at, self._zone, to.language)
        title = f"{course.title} ({course.name})"
        message = EmailMessage()
        message["From"] = formataddr((self._title, self._smtp.sender))
        message["To"] = to.email
        message["Subject"] = f"[{self._title}] {say(_SUBJECT, course=course.title, start=when)}"[
            :200
        ]
        message.set_content(
            say(_BODY, course=title, rigs=", ".join(rigs), when=when)
            + "\n"
            + (f"\n{booking.note}\n" if booking.note else "")
            + "\n"
            + say(_FOOTER, lab=self._title)
            + "\n"
        )
        return message

    def _send(self, message: EmailMessage) -> bool:
        smtp = self._smtp
        assert smtp is not None
        try:
            with smtplib.SMTP(smtp.host, smtp.port, timeout=10) as server:
                if smtp.starttls:
                    server.starttls()
                if smtp.username is not None:
                    password = os.environ.get(smtp.password_env or "", "")
                    server.login(smtp.username, password)
                server.send_message(message)
            return True
        except (OSError, smtplib.SMTPException) as exc:
            log.warning(
                "could not send a booking reminder via %s:%s: %s", smtp.host, smtp.port, exc
            )
            return False


def _require(who: Principal) -> None:
    if scope_of(who, Action.BOOKING_REMINDERS) is Scope.NONE:
        reach = (Scope.LAB, Scope.TAUGHT, Scope.SELF)
        raise AccessDeniedError(
            f"only {who_may(Action.BOOKING_REMINDERS, reach)} may {Action.BOOKING_REMINDERS}"
        )
