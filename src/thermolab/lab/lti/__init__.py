"""ThermoLab as an LTI 1.3 tool (LTI Advantage): launches, deep linking, roster, grades.

:class:`LtiService` holds the parts, each in its own module:

* :mod:`.platforms` — the LMSs a teacher registered;
* :mod:`.keys` — the tool's RSA keys, rotated, published as a JWKS;
* :mod:`.tokens` — checking a platform's ``id_token`` against its JWKS;
* :mod:`.launch` — OIDC login initiation and the launch (:mod:`.accounts`:
  who is signed in, which course);
* :mod:`.deep_linking` — the teacher's choice of what to link;
* :mod:`.handoffs` — a pending deep link and a new window's ticket, in the
  database, so that any web worker can finish a launch;
* :mod:`.roster` — NRPS roster synchronisation;
* :mod:`.grades` — the AGS grade outbox: ``LtiService.queue_grade`` is its ``queue_grade``;
* :mod:`.assignment_links` — assignments offered to deep linking, their marks
  queued for the LMS (:meth:`LtiService.follow_assignments`);
* :mod:`.services` — OAuth 2 client credentials and the HTTP calls.

JOSE is PyJWT (with ``cryptography``): RS256 signing and checking, JWK
import and export, and ``PyJWKClient``, which fetches a platform's JWKS, caches
it and fetches again once when a token carries an unknown ``kid`` (a key
rotation), with a 10 s cooldown so that made-up kids cannot make the lab hammer
the LMS. The LTI flow is written here. pylti1p3, the common LTI library, takes
bug fixes only, is synchronous and framework-bound (Django/Flask adapters whose
session, cookie and cache abstractions would have to be re-plumbed into FastAPI
and our database), and stores launch data in a cache we do not run; the flow on
a well-kept JOSE library is smaller and testable against our own database.
joserfc would have done as well; PyJWT was chosen for ``PyJWKClient``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable
from datetime import timedelta

from argon2 import PasswordHasher

from thermolab.lab.accounts.users import UserInfo
from thermolab.lab.assignments import AssignmentService
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import HandoffKind
from thermolab.lab.db.models import User
from thermolab.lab.lti.assignment_links import follow_assignments
from thermolab.lab.lti.deep_linking import DeepLinkRequests, LinkableItems, LinkItem
from thermolab.lab.lti.grades import GradeOutbox
from thermolab.lab.lti.handoffs import Handoffs
from thermolab.lab.lti.keys import ToolKeys
from thermolab.lab.lti.launch import LaunchOutcome, LtiLaunches
from thermolab.lab.lti.platforms import PlatformRegistry
from thermolab.lab.lti.roster import RosterSync
from thermolab.lab.lti.services import PlatformClient
from thermolab.lab.lti.tokens import JwksCache

__all__ = ["LtiService"]

log = logging.getLogger(__name__)

_WINDOW_LIFETIME = timedelta(minutes=2)
_KICK_INTERVAL = 5.0  # seconds between looks at the grade outbox


class LtiService:
    """Everything of the LTI tool, wired once for the lab.

    Parameters
    ----------
    db : Database
    clock : LabClock
    hasher : PasswordHasher
        Hashes the random passwords of accounts made by launches.
    rigs : iterable of (rig id, title)
        What deep linking offers (with each rig's guide pages).
    guide_sections : iterable of str
        The guide's sections.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        hasher: PasswordHasher,
        rigs: Iterable[tuple[str, str]],
        guide_sections: Iterable[str],
    ) -> None:
        self._db = db
        self.handoffs = Handoffs(db, clock)
        self.platforms = PlatformRegistry(db, clock)
        self.keys = ToolKeys(db, clock)
        self.jwks = JwksCache()
        self.launches = LtiLaunches(db, clock, hasher, self.jwks)
        self.client = PlatformClient(self.keys, clock)
        self.grades = GradeOutbox(db, clock, self.client)
        #: Queue a score for an LMS line item: :meth:`.GradeOutbox.queue_grade` itself
        #: (declared there once).
        self.queue_grade = self.grades.queue_grade
        #: Queue a lab user's mark for the LMS activities that link a target (what
        #: "an assignment was marked" calls): :meth:`.GradeOutbox.queue_for_user`.
        self.queue_grade_for_user = self.grades.queue_for_user
        self.roster = RosterSync(db, clock, hasher, self.client)
        self.linkable = LinkableItems()
        rig_list = list(rigs)
        sections = list(guide_sections)
        self.linkable.register(lambda: [LinkItem("rig", f"rig:{r}", t, r) for r, t in rig_list])
        self.linkable.register(
            lambda: [
                LinkItem("guide", f"guide:{r}/{s}", f"{t} — {s}", r)
                for r, t in rig_list
                for s in sections
            ]
        )
        self.deep_links = DeepLinkRequests(self.handoffs, self.keys, self.linkable)
        self._lock = threading.Lock()
        self._delivering: threading.Thread | None = None
        self._next_kick = 0.0

    def follow_assignments(self, assignments: AssignmentService) -> Callable[[], None]:
        """Offer ``assignments`` to deep linking and post their marks; return an unsubscribe.

        See :mod:`thermolab.lab.lti.assignment_links`.
        """
        return follow_assignments(
            self._db, assignments, self.linkable, self.queue_grade_for_user, self.kick
        )

    def kick(self) -> None:
        """Deliver due grades in a background thread (never blocks the caller)."""
        now = time.monotonic()
        with self._lock:
            if now < self._next_kick or (
                self._delivering is not None and self._delivering.is_alive()
            ):
                return
            self._next_kick = now + _KICK_INTERVAL
            self._delivering = threading.Thread(
                target=self._deliver, name="lti-grades", daemon=True
            )
            self._delivering.start()

    def close(self, timeout: float = 5.0) -> None:
        """Wait (a while) for a delivery in progress; rows it did not finish stay queued."""
        with self._lock:
            thread = self._delivering
            self._next_kick = float("inf")  # no more deliveries
        if thread is not None:
            thread.join(timeout)

    def _deliver(self) -> None:
        try:
            self.grades.deliver_due()
        except Exception:  # a failed look must not kill the next ones; rows stay queued
            log.exception("the LTI grade outbox could not be delivered")

    def hand_over(self, outcome: LaunchOutcome, path: str) -> str:
        """A one-time ticket (2 minutes) that opens the launch's login in a new window.

        Kept in the database: the new window's request may reach another worker.
        """
        return self.handoffs.put(
            HandoffKind.WINDOW,
            outcome.user.id,
            outcome.platform.id,
            {"path": path},
            _WINDOW_LIFETIME,
        )

    def take_over(self, ticket: str) -> tuple[UserInfo, str] | None:
        """The person and page of a ticket, once; ``None`` when unknown, used or expired."""
        found = self.handoffs.take(HandoffKind.WINDOW, ticket)
        if found is None:
            return None
        with self._db.read() as session:
            user = session.get(User, found.user_id)
            return None if user is None else (UserInfo.of(user), str(found.data["path"]))
