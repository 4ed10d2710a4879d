"""The lab as one object: database, accounts, sessions, access model and live rigs.

:class:`Lab` wires the services together for the HTTP app and the command
line; :func:`thermolab.lab.http.app.create_app` serves one over HTTP.
"""

from __future__ import annotations

import contextlib
import logging
import threading
from datetime import datetime, timedelta

from argon2 import PasswordHasher

from thermolab.errors import ThermoLabError
from thermolab.lab.access import AccessService, RigView
from thermolab.lab.accounts.login_sessions import SessionService
from thermolab.lab.accounts.name_book import NameBook
from thermolab.lab.accounts.security import LoginThrottle, default_password_hasher
from thermolab.lab.accounts.tokens import TokenService
from thermolab.lab.accounts.users import LoginsEnded, Principal, UserInfo, UserService
from thermolab.lab.agents import AgentHub, RemoteRuns
from thermolab.lab.analytics import AnalyticsService, assignment_state
from thermolab.lab.assignments import AssignmentService
from thermolab.lab.audit.log import AuditLog
from thermolab.lab.classes.assistants import AssistantService
from thermolab.lab.classes.authorize import Authorizer
from thermolab.lab.classes.booking_tools import BookingTools
from thermolab.lab.classes.bookings import BookingService
from thermolab.lab.classes.calendar_feeds import CalendarFeedService
from thermolab.lab.classes.course_settings import CourseSettingsService
from thermolab.lab.classes.courses import CourseService
from thermolab.lab.classes.reminders import ReminderService
from thermolab.lab.classes.retention import RetentionService
from thermolab.lab.classes.term import TermService
from thermolab.lab.clock import LabClock, SystemClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.error_messages import DEFAULT_LANGUAGE
from thermolab.lab.fleet.lease import DatabaseLease
from thermolab.lab.guides import SECTIONS, GuideImageService, GuideService
from thermolab.lab.listener import LabListener
from thermolab.lab.live.presence import Presence
from thermolab.lab.lti import LtiService
from thermolab.lab.outcomes import InputResult, OutputReading, StartupReport
from thermolab.lab.rig_image import rig_image
from thermolab.lab.rigs.camera import PictureCache
from thermolab.lab.rigs.devices import DesiredState, DeviceHub
from thermolab.lab.rigs.opener import RigOpener
from thermolab.lab.rigs.rig_settings import RigSettingsService
from thermolab.lab.runs import RunRecord, RunService
from thermolab.lab.runs.channels import ChannelResult, set_channel
from thermolab.lab.runs.where import RunsByRig
from thermolab.runner import Event

__all__ = ["Lab"]

log = logging.getLogger(__name__)

_PURGE_INTERVAL = timedelta(minutes=10)


class Lab:
    """A running lab.

    Parameters
    ----------
    config : LabConfig
    clock : LabClock, optional
        Wall clock (default :class:`~thermolab.lab.clock.SystemClock`).
    hasher : PasswordHasher, optional
        Argon2 hasher (default: argon2-cffi's recommended parameters).
    opener : RigOpener, optional
        Opens rig drivers; ``None`` runs without devices.
    database : Database, optional
        Default: the database named by the configuration.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from thermolab.lab.config import default_config
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     lab = Lab(default_config(Path(tmp)))
    ...     report = lab.start()
    ...     lab.close()
    >>> report.teachers
    0
    """

    def __init__(
        self,
        config: LabConfig,
        *,
        clock: LabClock | None = None,
        hasher: PasswordHasher | None = None,
        opener: RigOpener | None = None,
        database: Database | None = None,
        exclusive: bool = False,
    ) -> None:
        self.config = config
        self.clock: LabClock = clock or SystemClock()
        self.db = database or Database(config.database)
        # ``thermolab serve`` is the one server of its database (tests share one freely).
        self.lease = DatabaseLease(self.db, self.clock) if exclusive else None
        policy = config.access
        self.presence = Presence(self.clock, timeout=policy.client_timeout)
        self.hub = DeviceHub(config, opener, self.clock)
        # Teacher settings: first values from the file, then the database's, in force at once
        # (a twin's speed-up: on its clock when no run is going, else at the next START).
        self.settings = RigSettingsService(
            self.db, self.clock, config, self.hub.input_range, self.hub.follow_settings
        )
        # Logins that end (logout, expiry, new password, removed account) are announced
        # here; the live stream closes their sockets.
        self.logins_ended = LoginsEnded()
        self.users = UserService(
            self.db,
            self.clock,
            hasher or default_password_hasher(),
            logins_ended=self.logins_ended,
        )
        self.sessions = SessionService(
            self.db,
            self.clock,
            lifetime=policy.session_lifetime,
            idle_timeout=policy.session_idle_timeout,
            logins_ended=self.logins_ended,
        )
        self.courses = CourseService(
            self.db,
            self.clock,
            hasher or default_password_hasher(),
            logins_ended=self.logins_ended,
        )
        # Who may act on which course or person (the policy table against the rosters),
        # and the log of what they did.
        self.authorize = Authorizer(self.db)
        self.audit = AuditLog(self.db, self.clock)
        # Courses' teaching assistants (what they may do is the policy table's).
        self.assistants = AssistantService(self.db, self.clock)
        # Display names of the people the answers name (kept briefly).
        self.names = NameBook(self.db, self.clock)
        # Personal API tokens for scripts; revoked ones are announced like ended logins.
        self.tokens = TokenService(self.db, self.clock)
        # Courses' limits, in force on their booked rigs during their slots.
        self.course_settings = CourseSettingsService(self.db, self.clock)
        # Courses' booked slots on rigs (the turn rules apply them).
        self.bookings = BookingService(self.db, self.clock, config)
        # Students' own bookings, weekly series, calendar feeds, reminders (issue #24, item 7).
        self.booking_tools = BookingTools(self.db, self.clock, config, self.bookings)
        self.calendar_feeds = CalendarFeedService(self.db, self.clock, config.title)
        self.reminders = ReminderService(
            self.db, self.clock, config.smtp, config.title, config.time_zone
        )
        # The end of a term: closing, copying to the next, removing last term's students.
        self.term = TermService(self.db, self.clock, self.bookings)
        self.retention = RetentionService(
            self.db, self.clock, config.retention, self.audit, hasher or default_password_hasher()
        )
        # Each rig's guide pages: shipped defaults, teachers' revisions.
        self.guides = GuideService(self.db, self.clock, config)
        self.guide_images = GuideImageService(self.db, self.clock, config)
        # Assignments, hand-ins, automatic marks, grades (and the "submission marked" hook).
        self.assignments = AssignmentService(self.db, self.clock, config)
        # A course's figures, with each student's assignment state.
        self.analytics = AnalyticsService(self.db, self.clock, config, assignments=assignment_state)
        # The LTI 1.3 tool (issue #12): platforms, keys, launches, roster, the grade outbox.
        rigs = [(rig.id, rig.title) for rig in config.rigs]
        self.lti = LtiService(
            self.db, self.clock, hasher or default_password_hasher(), rigs, SECTIONS
        )
        self.lti.follow_assignments(self.assignments)  # deep links and marks to the LMS
        self.throttle = LoginThrottle(
            self.clock,
            failures_per_user=policy.login_failures_per_user,
            attempts_per_address=policy.login_attempts_per_address,
            window=policy.login_window,
        )
        self.access = AccessService(
            self.db, config, self.clock, self.hub, self.presence, on_change=self._reconcile
        )
        # A revoked (or expired) token's script is cut off: its turn ends and the rig is safe now.
        self.tokens.revoked.subscribe(self.end_token_turns)
        self.listeners: list[LabListener] = []
        # Remote rigs' hosts (thermolab agent); the run service sends their runs to them.
        self.agents = AgentHub(
            self.db, self.clock, config, self.access, self.hub, on_online=self._reconcile
        )
        self.runs = RunService(
            self.db,
            self.clock,
            self.access,
            self.hub,
            config,
            self._reconcile,
            on_run=self._run_changed,
            on_event=self._run_event,
        )
        #: The remote rigs (``agent = true``): their runs go to their hosts (a set, so that
        #: an in-process rig's START and reconcile cross no module of theirs).
        self.remote_rigs = frozenset(rig.id for rig in config.rigs if rig.agent)
        self.remote_runs = RemoteRuns(
            self.runs,
            self.agents,
            db=self.db,
            config=config,
            clock=self.clock,
            access=self.access,
            devices=self.hub,
            on_finished=self._reconcile,
            on_run=self._run_changed,
            on_event=self._run_event,
        )
        #: Every action on a rig's current run goes through this, here or on the rig's host.
        self.rig_runs = RunsByRig(self.runs, self.remote_runs, self.remote_rigs)
        self._last_purge: datetime | None = None
        self._pictures = PictureCache(ttl=0.5)
        self._sweep_lock = threading.Lock()
        self._report: StartupReport | None = None

    def start(self) -> StartupReport:
        """Migrate the database, put every rig in its safe state, end what a restart ended.

        Calling it again returns the first report and does nothing else.
        """
        if self._report is not None:
            return self._report
        self.db.upgrade()
        if self.lease is not None:
            # Before start-up touches any run or turn: another live server's are not ours.
            self.lease.acquire()
        faults = self.hub.open_all()
        self.settings.load()
        self.access.startup()
        self.agents.check(self.clock.now())  # no host has dialled in yet: none is granted
        for rig in self.config.rigs:
            self._reconcile(rig.id)
        for rig_id, message in faults.items():
            self.access.report_fault(rig_id, message)
        self._report = StartupReport(teachers=self.users.count_teachers(), faults=faults)
        return self._report

    def sweep(self) -> list[str]:
        """Apply run-out limits, hand rigs over, power idle rigs off; return rigs changed.

        The server calls this about once a second; tests call it after moving
        their clock.
        """
        with self._sweep_lock:
            now = self.clock.now()
            lease = self.lease
            if lease is not None and lease.held and not lease.renew():
                log.critical("another server process took over this database's lease")
            if lease is not None and lease.lost:
                return []  # turns and limits are the new holder's now (docs/fleet.md)
            self.hub.poll(now)
            self._announce_readings(now)
            for rig in self.config.rigs:
                fault = self.hub.fault(rig.id)
                if fault is not None:
                    self.access.report_fault(rig.id, fault)
            if self.remote_rigs:
                self.agents.check(now)
            changed = self.access.sweep()
            if self._last_purge is None or now - self._last_purge >= _PURGE_INTERVAL:
                self._last_purge = now
                self.sessions.purge_expired()
                self.tokens.purge_expired()
                self.lti.launches.purge_expired()
            self.lti.kick()  # the grade outbox, in its own thread
            self.reminders.kick()  # booking reminders due, in their own thread
            return changed

    def apply_input(self, rig_id: str, who: Principal, u: float) -> InputResult:
        """Validate, record and apply a controller's input (see ``AccessService.record_input``).

        During a run the input goes to the run, which applies it from its next
        sample on (``applied`` is then the value it will apply).
        """
        self.config.rig(rig_id)  # an unknown rig is a 404, before anything reads its device
        runs = self.rig_runs.of(rig_id)
        run_id = runs.running(rig_id)
        record = self.access.record_input(rig_id, who, u, run_id=run_id)
        applied: float | None
        if (
            run_id is not None
            and runs.set_input(rig_id, record.u, control_session=record.control_session) is not None
        ):
            applied = record.u
        else:
            applied = self.hub.apply(rig_id, record.u, controller_session=record.control_session)
            if (
                applied is None
                and rig_id in self.remote_rigs
                and self.agents.apply(rig_id, record.u)
            ):
                applied = record.u
        if applied is not None:
            self.access.mark_applied(record.id)
        fault = self.hub.fault(rig_id)
        if fault is not None:
            self.access.report_fault(rig_id, fault)
        return InputResult(rig_id, record.u, applied, record.at, record.id, run_id)

    def set_channel(self, rig_id: str, who: Principal, name: str, value: float) -> ChannelResult:
        """Set the rig's further input ``name`` (see :func:`.runs.channels.set_channel`)."""
        parts = (self.config, self.access, self.hub, self.rig_runs)
        return set_channel(*parts, (self.agents, self.remote_rigs), rig_id, who, name, value)

    def running(self, rig_id: str) -> int | None:
        """The id of the run going on the rig, in-process or on its host, if any."""
        return self.rig_runs.running(rig_id)

    def read_output(self, rig_id: str, who: Principal) -> OutputReading:
        """The rig's output: read now for its controller, the latest reading for others.

        Counts as the caller's heartbeat for the rig, like ``GET /api/rigs/{rig}``;
        the controller's read is also activity for the idle limit: a notebook's
        step test sets the heater once and then only reads the sensor for minutes,
        and is still using the rig (the time limit still ends the turn).
        """
        view = self.access.view(rig_id, who)
        fresh = view.access.role == "controller"
        idle_left = view.access.idle_time_left
        limit = view.config.idle_limit  # in force now (a course's during its slot)
        if fresh and idle_left is not None and limit is not None and idle_left < limit / 2:
            # Written at most twice per idle limit, so that reads stay cheap.
            with (
                contextlib.suppress(ThermoLabError),
                self.access.controlled(rig_id, who, "read it"),
            ):
                pass  # the turn just ended: a plain read
        reading = self.hub.read_now(rig_id) if fresh else None
        if reading is None:
            fresh = False
            reading = self.hub.reading(rig_id)
        fault = self.hub.fault(rig_id)
        if fault is not None:
            self.access.report_fault(rig_id, fault)
        return OutputReading(
            rig_id,
            None if reading is None else reading[0],
            None if reading is None else reading[1],
            self.hub.applied(rig_id),
            fresh,
            self.hub.channels(rig_id),
        )

    def set_service(self, rig_id: str, who: Principal, in_service: bool) -> RigView:
        """Take a rig in or out of service; clears its fault (teachers only)."""
        self.config.rig(rig_id)
        if who.is_teacher:
            self.hub.clear_fault(rig_id)
        return self.access.set_service(rig_id, who, in_service)

    def camera(self, rig_id: str, language: str = DEFAULT_LANGUAGE) -> bytes:
        """Return the rig's live image (JPEG): its camera, or a twin's state drawn
        with its words in ``language``.

        Raises
        ------
        NotFoundError
            For an unknown rig.
        CameraError
            If the rig's camera cannot be read.
        """
        return rig_image(self.config, self.access, self.hub, self._pictures, rig_id, language)

    def remove_user(self, username: str) -> UserInfo:
        """Remove an account; rigs it controlled go to the next in their queues."""
        tokens = self.tokens.ids_of(self.users.get(username).id)
        info = self.users.remove(username)
        self.tokens.revoked.publish(tokens)  # their live sockets close at once
        self.access.sweep()
        for rig in self.config.rigs:
            self._reconcile(rig.id)
        return info

    def end_token_turns(self, token_ids: frozenset[int]) -> None:
        """End the turns and queue places of revoked tokens (``AccessService.end_token_turns``)."""
        self.access.end_token_turns(token_ids)

    def close(self) -> None:
        """End every run, leave every rig safe and close the database connections."""
        self.runs.shutdown()
        self.hub.close()
        self.lti.close()
        if self.lease is not None:
            self.lease.release()
        self.db.close()

    def _announce_readings(self, now: datetime) -> None:
        # The idle monitoring: the reading just taken of each powered rig with no run.
        for rig in self.config.rigs:
            reading = self.hub.reading(rig.id)
            if reading is None or reading[1] != now or not self.hub.powered(rig.id):
                continue
            if self.runs.running(rig.id) is not None or self.remote_runs.running(rig.id):
                continue
            channels = self.hub.channels(rig.id)
            for listener in self.listeners:
                listener.reading(rig.id, self.hub.applied(rig.id), reading[0], now, channels)

    def add_listener(self, listener: LabListener) -> None:
        """Tell ``listener`` about access changes, runs and readings from now on."""
        self.listeners.append(listener)

    def _run_changed(self, rig_id: str, event: str, record: RunRecord) -> None:
        for listener in self.listeners:
            listener.run_changed(rig_id, event, record)

    def _run_event(self, rig_id: str, run_id: int, event: Event) -> None:
        for listener in self.listeners:
            listener.run_event(rig_id, run_id, event)

    def _reconcile(self, rig_id: str) -> None:
        cfg = self.config.rig(rig_id)
        with self.hub.locked(rig_id):
            power, controller = self.access.desired(rig_id)
            # A run belongs to a turn: when the turn is over, so is the run.
            self.rig_runs.control_changed(rig_id, controller)
            desired = DesiredState(power=power, controller_session=controller)
            handed_over = self.hub.reconcile(rig_id, desired, cfg.cooldown.input)
            if rig_id in self.remote_rigs:
                self.agents.sync_power(rig_id, hand_over=handed_over)
        for listener in self.listeners:
            listener.access_changed(rig_id)
