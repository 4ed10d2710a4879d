"""Every route as every kind of user, inside and outside the object's course (issue #25).

The route table is the app's own ``/openapi.json``: a route missing from
:data:`EXPECTED` fails the test, so a new route must say who may use it. Each
route is tried by an administrator (``root``), a teacher (``tina``, who
teaches ``mine``), a teaching assistant (``tara``, a student's account that
assists ``mine``) and a student (``ana``, in ``mine``), on an object of
``mine`` ("in") and of ``theirs`` (taught by ``otto``, with student ``olga``;
"out"). A try the table does not allow must be refused with 403 or 404 — not
a 422, so every body below is one the route would accept — and a try it
allows must not be refused with 403. One lab, one app: a few seconds.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.assignment_models import Assignment
from thermolab.lab.db.lti_models import LtiIdentity
from thermolab.lab.http.app import create_app
from thermolab.lab.runs.request import RunRequest

from .conftest import PASSWORD, LabFactory
from .test_runs import twin_lab


class Kind(enum.Enum):
    """Who may use a route, on which objects."""

    PUBLIC = "no login (not tried)"
    ANYONE = "any logged-in user; the object is lab-wide or their own by construction"
    TEACHER = "any teacher, lab-wide (rigs in class, guides, creating a course)"
    ADMIN = "lab administrators only"
    COURSE_TEACHER = "the object's course's teachers, and administrators"
    COURSE_STAFF = "the object's course's teachers and assistants, and administrators"
    COURSE_MEMBER = "the object's course's members, and administrators"
    STUDENT_OF_COURSE = "the object's course's students only (handing in)"
    OWN_OR_TEACHER = (
        "the object's owner (and, read only, their lab group mates); any teacher (runs)"
    )
    OWN = "the object's owner only"


K = Kind
EXPECTED: dict[str, Kind] = {
    "GET /api/session": K.PUBLIC,
    "POST /api/session": K.PUBLIC,
    "DELETE /api/session": K.PUBLIC,
    "GET /api/version": K.PUBLIC,
    "GET /api/privacy": K.PUBLIC,
    "POST /api/enrol": K.PUBLIC,
    "GET /api/lti/login": K.PUBLIC,
    "POST /api/lti/login": K.PUBLIC,
    "POST /api/lti/launch": K.PUBLIC,
    "GET /api/lti/continue": K.PUBLIC,
    "GET /api/lti/jwks": K.PUBLIC,
    "GET /api/rigs": K.ANYONE,
    "GET /api/rigs/{rig_id}": K.ANYONE,
    "POST /api/rigs/{rig_id}/control": K.ANYONE,
    "DELETE /api/rigs/{rig_id}/control": K.ANYONE,
    "POST /api/rigs/{rig_id}/heartbeat": K.ANYONE,
    "POST /api/rigs/{rig_id}/control/more-time": K.ANYONE,
    "PUT /api/rigs/{rig_id}/control/speedup": K.ANYONE,
    "PUT /api/rigs/{rig_id}/input": K.ANYONE,
    "PUT /api/rigs/{rig_id}/channels/{name}": K.ANYONE,  # the controller only (its tests)
    "GET /api/rigs/{rig_id}/control-sessions": K.ANYONE,
    "GET /api/rigs/{rig_id}/camera": K.ANYONE,
    "GET /api/rigs/{rig_id}/reading": K.ANYONE,
    "POST /api/rigs/{rig_id}/runs": K.ANYONE,
    "POST /api/rigs/{rig_id}/runs/current/stop": K.ANYONE,
    "GET /api/runs": K.ANYONE,
    "GET /api/methods": K.ANYONE,
    "GET /api/me/export": K.ANYONE,
    "GET /api/tokens": K.ANYONE,
    "POST /api/tokens": K.ANYONE,
    "GET /api/control": K.ANYONE,
    "GET /api/rigs/{rig_id}/loop": K.ANYONE,
    "PUT /api/rigs/{rig_id}/runs/current/mode": K.ANYONE,
    "PUT /api/rigs/{rig_id}/runs/current/setpoint": K.ANYONE,
    "PUT /api/rigs/{rig_id}/runs/current/gains": K.ANYONE,
    "PUT /api/rigs/{rig_id}/runs/current/fan": K.ANYONE,
    "GET /api/rigs/{rig_id}/guide": K.ANYONE,
    "POST /api/guide-preview": K.ANYONE,
    "GET /api/guide-images/{image_id}": K.ANYONE,
    "GET /api/assignments": K.ANYONE,
    "GET /api/bookings": K.ANYONE,
    "GET /api/rigs/{rig_id}/next-chance": K.ANYONE,
    "GET /api/courses": K.ANYONE,  # a teacher gets their courses, a student none
    "GET /api/lti/grades": K.TEACHER,  # filtered to the teacher's courses (checked below)
    "POST /api/rigs/{rig_id}/control/extend": K.TEACHER,
    "POST /api/rigs/{rig_id}/control/kick": K.TEACHER,
    "PUT /api/rigs/{rig_id}/service": K.TEACHER,
    "PUT /api/rigs/{rig_id}/guide/{section}": K.TEACHER,
    "GET /api/rigs/{rig_id}/guide/{section}/revisions": K.TEACHER,
    "GET /api/rigs/{rig_id}/guide-revisions/{revision_id}": K.TEACHER,
    "POST /api/rigs/{rig_id}/guide-revisions/{revision_id}/restore": K.TEACHER,
    "POST /api/rigs/{rig_id}/guide-images": K.TEACHER,
    "GET /api/rigs/{rig_id}/guide-images": K.TEACHER,
    "GET /api/rigs/{rig_id}/settings": K.TEACHER,
    "POST /api/courses": K.TEACHER,
    "GET /api/lti/tool": K.TEACHER,
    "GET /api/agents": K.TEACHER,
    "GET /api/users": K.ADMIN,
    "POST /api/users": K.ADMIN,
    "DELETE /api/users/{username}": K.ADMIN,
    "POST /api/users/{username}/forget": K.ADMIN,
    "PUT /api/users/{username}/admin": K.ADMIN,
    "PUT /api/rigs/{rig_id}/settings": K.ADMIN,
    "GET /api/lti/platforms": K.ADMIN,
    "POST /api/lti/platforms": K.ADMIN,
    "DELETE /api/lti/platforms/{platform_id}": K.ADMIN,
    "POST /api/lti/keys/rotate": K.ADMIN,
    "GET /api/audit": K.ADMIN,
    "GET /api/audit.csv": K.ADMIN,
    "PUT /api/users/{username}/password": K.COURSE_TEACHER,
    "POST /api/users/{username}/password-reset": K.COURSE_TEACHER,
    "GET /api/courses/{course}": K.COURSE_STAFF,
    "PUT /api/courses/{course}/roster": K.COURSE_TEACHER,
    "POST /api/courses/{course}/enrol-code": K.COURSE_TEACHER,
    "PUT /api/courses/{course}/rigs": K.COURSE_TEACHER,
    "PUT /api/courses/{course}/assistants/{username}": K.COURSE_TEACHER,
    "DELETE /api/courses/{course}/assistants/{username}": K.COURSE_TEACHER,
    "POST /api/courses/{course}/assignments": K.COURSE_TEACHER,
    "PUT /api/assignments/{assignment_id}": K.COURSE_TEACHER,
    "GET /api/assignments/{assignment_id}/submissions": K.COURSE_STAFF,
    "GET /api/courses/{course}/grades.csv": K.COURSE_STAFF,
    "GET /api/assignments/{assignment_id}/standings": K.COURSE_STAFF,
    "PUT /api/assignments/{assignment_id}/overrides/{username}": K.COURSE_TEACHER,
    "DELETE /api/assignments/{assignment_id}/overrides/{username}": K.COURSE_TEACHER,
    "PUT /api/assignments/{assignment_id}/extensions/{username}": K.COURSE_TEACHER,
    "DELETE /api/assignments/{assignment_id}/extensions/{username}": K.COURSE_TEACHER,
    "GET /api/courses/{course}/groups": K.COURSE_STAFF,
    "POST /api/courses/{course}/groups": K.COURSE_TEACHER,
    "DELETE /api/courses/{course}/groups/{group_id}": K.COURSE_TEACHER,
    "POST /api/bookings": K.COURSE_TEACHER,
    "PUT /api/bookings/{booking}": K.COURSE_TEACHER,
    "DELETE /api/bookings/{booking}": K.COURSE_TEACHER,
    # The booking tools (issue #24, item 7).
    "GET /api/courses/{course}/booking-quota": K.COURSE_TEACHER,
    "PUT /api/courses/{course}/booking-quota": K.COURSE_TEACHER,
    "POST /api/courses/{course}/own-bookings": K.STUDENT_OF_COURSE,
    "POST /api/booking-series": K.COURSE_TEACHER,
    "GET /api/own-bookings": K.ANYONE,  # the reader's own courses
    "GET /api/calendar-feeds": K.ANYONE,  # the reader's own
    "POST /api/calendar-feeds": K.ANYONE,  # of the reader's courses (checked in its test)
    "DELETE /api/calendar-feeds/{feed_id}": K.ANYONE,  # another's is a 404 (its test)
    "GET /api/calendar/{token}": K.PUBLIC,  # the address is the secret
    "GET /api/reminders": K.ANYONE,
    "PUT /api/reminders": K.ANYONE,
    "DELETE /api/reminders": K.ANYONE,
    "GET /api/courses/{course}/analytics": K.COURSE_STAFF,
    "GET /api/courses/{course}/analytics/students.csv": K.COURSE_STAFF,
    "GET /api/courses/{course}/analytics/rigs.csv": K.COURSE_STAFF,
    "POST /api/lti/courses/{course}/roster": K.COURSE_TEACHER,
    "POST /api/lti/grades/{grade_id}/retry": K.COURSE_TEACHER,
    "PUT /api/courses/{course}/settings": K.COURSE_TEACHER,
    "GET /api/courses/{course}/settings": K.COURSE_TEACHER,
    "GET /api/assignments/{assignment_id}": K.COURSE_MEMBER,
    "POST /api/assignments/{assignment_id}/submissions": K.STUDENT_OF_COURSE,
    "POST /api/courses/{course}/close": K.COURSE_TEACHER,
    "POST /api/courses/{course}/copy": K.COURSE_TEACHER,
    "POST /api/assignments/{assignment_id}/publish": K.COURSE_TEACHER,
    "POST /api/courses/{course}/reopen": K.ADMIN,
    "GET /api/courses/{course}/leavers": K.ADMIN,
    "POST /api/courses/{course}/purge-students": K.ADMIN,
    "GET /api/runs/{run_id}": K.OWN_OR_TEACHER,
    "GET /api/runs/{run_id}/samples.csv": K.OWN_OR_TEACHER,
    "GET /api/runs/{run_id}/export.json": K.OWN_OR_TEACHER,
    "GET /api/runs/{run_id}/tuning": K.OWN_OR_TEACHER,
    "DELETE /api/tokens/{token_id}": K.OWN,
    "GET /api/lti/deep-links/{key}": K.OWN,
    "POST /api/lti/deep-links/{key}": K.OWN,
}

ACTORS = ("root", "tina", "tara", "ana")
SIDES = ("in", "out")


def allowed(kind: Kind, actor: str, side: str) -> bool:
    """What the policy table promises: may ``actor`` use a ``kind`` route on a ``side`` object?"""
    admin, teacher = actor == "root", actor in ("root", "tina")
    inside = side == "in"
    return {
        K.ANYONE: True,
        K.TEACHER: teacher,
        K.ADMIN: admin,
        K.COURSE_TEACHER: admin or (teacher and inside),
        K.COURSE_STAFF: admin or (actor in ("tina", "tara") and inside),
        K.COURSE_MEMBER: admin or inside,
        K.STUDENT_OF_COURSE: actor == "ana" and inside,
        K.OWN_OR_TEACHER: teacher or (actor == "ana" and inside),  # the "in" run is ana's
        K.OWN: inside,
    }[kind]


def _assignment_body() -> dict[str, Any]:
    return {
        "title": "Step response",
        "rig": "twin",
        "methods": ["lsm"],
        "deadline": "2030-01-01T12:00:00+00:00",
    }


def _slot(hours: int) -> dict[str, str]:
    start = datetime(2031, 1, 1, tzinfo=UTC) + timedelta(hours=hours)
    return {
        "startsAt": start.isoformat(),
        "endsAt": (start + timedelta(minutes=30)).isoformat(),
    }


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def world(make_lab: LabFactory) -> Iterator[dict[str, Any]]:
    """The lab, the clients of root, tina and ana, and each route's objects in and out."""
    lab = twin_lab(make_lab)
    add = lab.users.add
    root = add("root", PASSWORD, "teacher", admin=True)
    tina, otto = add("tina", PASSWORD, "teacher"), add("otto", PASSWORD, "teacher")
    people = {"root": root, "tina": tina, "otto": otto}
    for name in ("ana", "olga", "tara", "helper", "pw_in", "pw_out", "gone_in", "gone_out"):
        people[name] = add(name, PASSWORD, "student")
    lab.courses.create("mine", "Mine", "tina")
    lab.courses.create("theirs", "Theirs", "otto")
    lab.courses.import_class_list("mine", b"username,display_name\nana,A\npw_in,P\ngone_in,G\n")
    lab.courses.import_class_list(
        "theirs", b"username,display_name\nolga,O\npw_out,P\ngone_out,G\n"
    )
    lab.assistants.add("mine", "tara")
    principal = {n: Principal(u.id, u.username, u.role, admin=u.admin) for n, u in people.items()}
    runs = {}
    for who in ("ana", "olga"):
        lab.access.request_control("twin", principal[who])
        request = RunRequest(dt=1.0, samples=20, signal="step:0:10@5", methods=("lsm",))
        runs[who] = lab.runs.start("twin", principal[who], request).id
        lab.runs.wait("twin", timeout=60)
        lab.access.release("twin", principal[who])
    tokens = {
        n: lab.tokens.create(principal[n], "t").info.id
        for n in ("root", "tina", "tara", "ana", "olga")
    }
    platform = lab.lti.platforms.register(
        issuer="http://127.0.0.1:9",
        client_id="c",
        auth_login_url="http://127.0.0.1:9/auth",
        token_url="http://127.0.0.1:9/token",
        jwks_url="http://127.0.0.1:9/jwks",
        deployment_ids=["d"],
    )
    with lab.db.write() as session:
        for who in ("ana", "olga"):
            session.add(LtiIdentity(platform_id=platform.id, sub=who, user_id=people[who].id))
    grades = {
        who: lab.lti.grades.queue_grade(
            platform_id=platform.id,
            lineitem_url="http://127.0.0.1:9/items/1",
            sub=who,
            score_given=1.0,
            score_maximum=1.0,
        )
        for who in ("ana", "olga")
    }
    draft = _assignment_body()
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    clients: dict[str, TestClient] = {}
    for name in ("root", "tina", "otto", "tara", "ana"):
        client = TestClient(app)
        answer = client.post("/api/session", json={"username": name, "password": PASSWORD})
        assert answer.status_code == 200, answer.text
        clients[name] = client
    assignments = {
        side: clients[teacher].post(f"/api/courses/{course}/assignments", json=draft).json()["id"]
        for side, teacher, course in (("in", "tina", "mine"), ("out", "otto", "theirs"))
    }
    bookings = {
        side: clients[teacher]
        .post("/api/bookings", json={"course": course, "rigs": ["other"], **_slot(hour)})
        .json()["id"]
        for side, teacher, course, hour in (("in", "tina", "mine", 0), ("out", "otto", "theirs", 2))
    }
    groups = {
        side: lab.assignments.groups.create(course, principal[teacher], "bench 1", students).id
        for side, teacher, course, students in (
            ("in", "tina", "mine", ["ana", "pw_in"]),
            ("out", "otto", "theirs", ["olga", "pw_out"]),
        )
    }
    # Students may book for themselves in both courses (the quota is not what is tried).
    for teacher, course in (("tina", "mine"), ("otto", "theirs")):
        quota = {"minutesPerWeek": 600}
        assert clients[teacher].put(f"/api/courses/{course}/booking-quota", json=quota).is_success
    yield {
        "lab": lab,
        "group_id": groups,
        "clients": clients,
        "course": {"in": "mine", "out": "theirs"},
        "username": {"in": "pw_in", "out": "pw_out"},
        "gone": {"in": "gone_in", "out": "gone_out"},
        "run_id": {"in": runs["ana"], "out": runs["olga"]},
        "token_id": tokens,
        "assignment_id": assignments,
        "booking": bookings,
        "grade_id": {"in": grades["ana"], "out": grades["olga"]},
        "platform_id": platform.id,
    }
    for client in clients.values():
        client.close()


def _request(world: dict[str, Any], route: str, actor: str, side: str) -> dict[str, Any]:
    """The method, URL and body of one try: path parameters filled with the side's objects."""
    method, path = route.split(" ", 1)
    values = {
        "rig_id": "twin",
        "section": "theory",
        "revision_id": "1",
        "image_id": "1",
        "key": "no-such-request",
        "platform_id": str(world["platform_id"]),
        "course": world["course"][side],
        "username": world["username"][side],
        "run_id": str(world["run_id"][side]),
        "assignment_id": str(world["assignment_id"][side]),
        "booking": str(world["booking"][side]),
        "grade_id": str(world["grade_id"][side]),
        "group_id": str(world["group_id"][side]),
        # A token of one's own ("in"), or of someone else.
        "token_id": str(world["token_id"][actor if side == "in" else "olga"]),
    }
    if route in ("DELETE /api/users/{username}", "POST /api/users/{username}/forget"):
        values["username"] = world["gone"][side]
    if "/assistants/" in route:  # made an assistant, then removed (deletions come last)
        values["username"] = "helper"
    url = path.format(**values)
    body = _BODIES.get(route)
    if callable(body):
        body = body(world, side)
    request: dict[str, Any] = {"method": method, "url": url}
    if route == "PUT /api/courses/{course}/roster":
        request["content"] = b"username,display_name\nnewbie,Newbie\n"
        request["headers"] = {"content-type": "text/csv"}
    elif route == "POST /api/rigs/{rig_id}/guide-images":
        request["files"] = {"file": ("a.png", _PNG, "image/png")}
    elif route == "POST /api/lti/deep-links/{key}":
        request["data"] = {"target": "rig:twin"}
    elif body is not None:
        request["json"] = body
    return request


_PNG = bytes.fromhex(
    "89504e470d0a1a0a0000000d4948445200000001000000010806000000"
    "1f15c4890000000d4944415478"
    "9c6360000002000001e221bc330000000049454e44ae426082"
)

_BODIES: dict[str, Any] = {
    "POST /api/users/{username}/forget": {"runs": "keep"},
    "POST /api/rigs/{rig_id}/control/extend": {"seconds": 60},
    "POST /api/rigs/{rig_id}/control/kick": {},
    "PUT /api/rigs/{rig_id}/service": {"inService": True},
    "PUT /api/rigs/{rig_id}/guide/{section}": {"markdown": "# Theory"},
    "POST /api/courses": {"name": "another", "title": "Another"},
    "POST /api/users": {"username": "newcomer", "password": "a long new secret", "role": "student"},
    "PUT /api/users/{username}/admin": {"admin": False},
    "PUT /api/rigs/{rig_id}/settings": {"version": 1, "values": {}},
    "POST /api/lti/platforms": {
        "issuer": "https://other.example",
        "clientId": "x",
        "authLoginUrl": "https://other.example/auth",
        "tokenUrl": "https://other.example/token",
        "jwksUrl": "https://other.example/jwks",
        "deploymentIds": ["d"],
    },
    "PUT /api/users/{username}/password": {
        "password": "another long secret",
        "currentPassword": PASSWORD,
    },
    "POST /api/users/{username}/password-reset": {"currentPassword": PASSWORD},
    "PUT /api/courses/{course}/rigs": {"rigs": ["twin"]},
    "POST /api/courses/{course}/assignments": _assignment_body(),
    "PUT /api/assignments/{assignment_id}": _assignment_body(),
    "POST /api/bookings": lambda world, side: {
        "course": world["course"][side],
        "rigs": ["other"],
        **_slot(10 if side == "in" else 12),
    },
    "PUT /api/bookings/{booking}": lambda world, side: {
        "rigs": ["other"],
        **_slot(0 if side == "in" else 2),
    },
    "PUT /api/courses/{course}/booking-quota": {"minutesPerWeek": 600},
    "POST /api/courses/{course}/own-bookings": {"rig": "twin", **_slot(30)},
    "POST /api/booking-series": lambda world, side: {
        "course": world["course"][side],
        "rigs": ["other"],
        **_slot(20 if side == "in" else 22),
        "until": "2031-01-01",
    },
    "PUT /api/courses/{course}/settings": {"version": 0, "values": {}},
    "POST /api/courses/{course}/copy": {"name": "next-term", "shiftDays": 182},
    # Not the list of leavers: refused as stale (409), so nobody the other tries need goes.
    "POST /api/courses/{course}/purge-students": {"students": ["nobody"], "runs": "keep"},
    "PUT /api/assignments/{assignment_id}/overrides/{username}": {"mark": 9.5, "comment": "ok"},
    "PUT /api/assignments/{assignment_id}/extensions/{username}": {
        "deadline": "2030-02-01T12:00:00+00:00"
    },
    "POST /api/courses/{course}/groups": lambda world, side: {
        "name": "bench 2",
        "members": [world["gone"][side], world["username"][side]],
    },
    "POST /api/assignments/{assignment_id}/submissions": lambda world, side: {
        "runId": world["run_id"]["in"],
        "K": 0.14,
        "tau": 250.0,
    },
}


def _spec_routes(world: dict[str, Any]) -> list[str]:
    app = world["clients"]["root"].app
    spec = app.openapi()  # type: ignore[attr-defined]
    return [f"{m.upper()} {p}" for p, ops in spec["paths"].items() for m in ops]


def test_every_route_is_in_the_expected_table(world: dict[str, Any]) -> None:
    routes = _spec_routes(world)
    assert sorted(set(routes) - set(EXPECTED)) == [], "routes with no expected scope"
    assert sorted(set(EXPECTED) - set(routes)) == [], "expected routes the app lacks"


@pytest.mark.slow
def test_no_route_answers_2xx_outside_its_scope(world: dict[str, Any]) -> None:
    clients = world["clients"]
    tries = [
        (route, actor, side)
        for route in _spec_routes(world)
        if EXPECTED[route] not in (K.PUBLIC, K.ANYONE)
        for actor in ACTORS
        for side in SIDES
    ]
    wrong: list[str] = []
    # Refusals first (they change nothing); then the allowed tries, deletions last.
    refused = [t for t in tries if not allowed(EXPECTED[t[0]], t[1], t[2])]
    permitted = sorted(
        (t for t in tries if allowed(EXPECTED[t[0]], t[1], t[2])),
        key=lambda t: t[0].startswith("DELETE"),
    )
    for route, actor, side in refused:
        answer = clients[actor].request(**_request(world, route, actor, side))
        if answer.status_code not in (403, 404):
            wrong.append(f"{actor} {side}: {route} -> {answer.status_code} {answer.text[:120]}")
    for route, actor, side in permitted:
        answer = clients[actor].request(**_request(world, route, actor, side))
        if answer.status_code in (401, 403):
            wrong.append(f"{actor} {side}: {route} refused -> {answer.text[:120]}")
    assert wrong == [], "\n".join(wrong)
    assert len(refused) > 100


def test_teachers_see_only_their_courses_and_their_students_grades(
    world: dict[str, Any],
) -> None:
    tina, root = world["clients"]["tina"], world["clients"]["root"]
    assert [c["name"] for c in tina.get("/api/courses").json()] == ["mine"]
    assert {c["name"] for c in root.get("/api/courses").json()} >= {"mine", "theirs"}
    assert [g["sub"] for g in tina.get("/api/lti/grades").json()] == ["ana"]
    assert sorted(g["sub"] for g in root.get("/api/lti/grades").json()) == ["ana", "olga"]
    assert world["clients"]["ana"].get("/api/courses").status_code == 403
    # An assistant lists the course they assist, and no LMS grades.
    tara = world["clients"]["tara"]
    assert [c["name"] for c in tara.get("/api/courses").json()] == ["mine"]
    assert tara.get("/api/lti/grades").status_code == 403


def test_an_assistant_reads_their_course_and_changes_nothing_in_it(
    world: dict[str, Any],
) -> None:
    tara, tina = world["clients"]["tara"], world["clients"]["tina"]
    roster = tara.get("/api/courses/mine").json()["members"]
    assert {m["username"]: m["role"] for m in roster}["tara"] == "assistant"
    assert "ana" in tara.get("/api/courses/mine/grades.csv").text
    # A draft is seen by the course's teachers and assistants, not its students.
    draft = {**_assignment_body(), "title": "Draft"}
    made = tina.post("/api/courses/mine/assignments", json=draft).json()["id"]
    with world["lab"].db.write() as session:
        session.get(Assignment, made).draft = True
    assert tara.get(f"/api/assignments/{made}").status_code == 200
    assert world["clients"]["ana"].get(f"/api/assignments/{made}").status_code == 403
    # What makes the course is its teachers': each refused with the policy's words.
    refused = tara.put("/api/courses/mine/rigs", json={"rigs": ["twin"]})
    assert refused.status_code == 403
    assert "only a teacher of course 'mine'" in refused.json()["detail"]
    assert tara.put("/api/courses/mine/assistants/helper").status_code == 403
    assert tara.post("/api/courses/mine/assignments", json=draft).status_code == 403
    # Someone already in the course is not made its assistant; a removed one reads nothing.
    assert tina.put("/api/courses/mine/assistants/ana").status_code == 409
    assert tina.delete("/api/courses/mine/assistants/tara").status_code == 200
    assert tara.get("/api/courses/mine").status_code == 403
    assert tara.get("/api/courses").status_code == 403
