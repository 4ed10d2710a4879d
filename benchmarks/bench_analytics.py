"""Class analytics of a large class: the lab's grouped SQL against a per-student ORM loop.

Builds a course of ``--students`` students, each with ``--runs`` runs on two
rigs (a turn, a queue wait and two methods' stored results with
``--trajectory``-sample trajectories per run) and power changes, in a fresh
SQLite file (or a PostgreSQL schema with ``--postgres URL``), then times
``AnalyticsService.course`` (best of ``--repeat``) and, as the peer measured
in the same run, the obvious ORM code: per student, read their turns, runs
and method results as objects (the results' JSON whole) and compute in
Python. Both must give the same control time and run counts.

    .venv/bin/python benchmarks/bench_analytics.py
    .venv/bin/python benchmarks/bench_analytics.py --students 200 --runs 10 \\
        --postgres postgresql+psycopg://postgres@127.0.0.1:5432/test
"""

from __future__ import annotations

import argparse
import tempfile
import time
import uuid
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import create_engine, select, text
from sqlalchemy.engine import make_url

from thermolab.lab.clock import ManualClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import (
    ControlSession,
    Course,
    CourseMember,
    MethodResultRow,
    QueueEntry,
    Run,
    User,
)
from thermolab.lab.db.power_models import PowerChange
from thermolab.lab.service import Lab

START = datetime(2026, 3, 1, tzinfo=UTC)


def _result(k: float, points: int) -> dict[str, Any]:
    return {
        "latest": {"K": k, "tau": 250.0, "valid": True, "extras": {"theta": 1.0, "warnings": []}},
        "final": True,
        "error": None,
        "stats": {"converged": True},
        "trajectory": {
            "k": list(range(points)),
            "K": [k] * points,
            "tau": [250.0] * points,
            "valid": [True] * points,
        },
    }


def build(lab: Lab, students: int, runs: int, points: int) -> None:
    """Fill the lab's database with a class and its history."""
    with lab.db.write() as s:
        course = Course(name="big", title="Big class", enrol_code="BIGCLASS23", created_at=START)
        s.add(course)
        s.flush()
        users = [
            User(
                username=f"s{i:04d}",
                display_name=f"Student {i}",
                role="student",
                password_hash="x",
                created_at=START,
                password_changed_at=START,
            )
            for i in range(students)
        ]
        s.add_all(users)
        s.flush()
        s.add_all(
            CourseMember(course_id=course.id, user_id=u.id, role="student", joined_at=START)
            for u in users
        )
        ticket = 0
        for j in range(runs):
            for i, user in enumerate(users):
                rig = ("twin", "other")[i % 2]
                at = START + timedelta(minutes=10 * (j * students + i))
                ticket += 1
                s.add(
                    QueueEntry(
                        rig_id=rig,
                        user_id=user.id,
                        ticket=ticket,
                        joined_at=at - timedelta(seconds=30 + i % 50),
                        last_heartbeat_at=at,
                        left_at=at,
                        leave_reason="promoted",
                    )
                )
                s.add(
                    ControlSession(
                        rig_id=rig,
                        user_id=user.id,
                        username=user.username,
                        started_at=at,
                        deadline=at + timedelta(seconds=300),
                        last_heartbeat_at=at,
                        last_activity_at=at,
                        ended_at=at + timedelta(seconds=240),
                        end_reason="released",
                    )
                )
                s.add(PowerChange(rig_id=rig, at=at, state="on"))
                s.add(PowerChange(rig_id=rig, at=at + timedelta(seconds=300), state="off"))
                run = Run(
                    rig_id=rig,
                    user_id=user.id,
                    status="finished",
                    dt=1.0,
                    n_samples=points,
                    signal="step:0:5@1",
                    methods=["lsm", "wlsm"],
                    meta={},
                    started_at=at + timedelta(seconds=5),
                    ended_at=at + timedelta(seconds=200),
                    end_reason="completed",
                    samples_stored=points,
                )
                s.add(run)
                s.flush()
                for method in ("lsm", "wlsm"):
                    s.add(
                        MethodResultRow(
                            run_id=run.id,
                            label=method,
                            method=method,
                            params={},
                            result=_result(0.14 + 0.001 * j, points),
                            created_at=at,
                        )
                    )


def orm_loop(lab: Lab, end: datetime) -> dict[str, tuple[float, int]]:
    """The peer: per student, their rows as objects, figures computed in Python."""
    out = {}
    with lab.db.read() as s:
        course = s.scalars(select(Course).where(Course.name == "big")).one()
        members = s.scalars(
            select(User)
            .join(CourseMember, CourseMember.user_id == User.id)
            .where(CourseMember.course_id == course.id)
        ).all()
        for user in members:
            turns = s.scalars(select(ControlSession).where(ControlSession.user_id == user.id))
            seconds = sum(
                ((t.ended_at or end) - t.started_at).total_seconds()
                for t in turns
                if t.started_at < end
            )
            runs = s.scalars(select(Run).where(Run.user_id == user.id)).all()
            latest: dict[str, Any] = {}
            for run in runs:
                for row in s.scalars(
                    select(MethodResultRow).where(MethodResultRow.run_id == run.id)
                ):
                    latest[row.method] = row.result["latest"]
            out[user.username] = (seconds, len(runs))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--runs", type=int, default=5, help="runs per student")
    parser.add_argument("--trajectory", type=int, default=500, help="samples per stored trajectory")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--postgres", help="a PostgreSQL URL (a schema of its own is used)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        schema = None
        if args.postgres:
            schema = f"bench_analytics_{uuid.uuid4().hex[:8]}"
            admin = create_engine(args.postgres, isolation_level="AUTOCOMMIT")
            with admin.connect() as c:
                c.execute(text(f'CREATE SCHEMA "{schema}"'))
            url = (
                make_url(args.postgres)
                .update_query_dict({"options": f"-csearch_path={schema}"})
                .render_as_string(hide_password=False)
            )
        else:
            url = f"sqlite:///{Path(tmp) / 'bench.sqlite3'}"
        clock = ManualClock(START)
        config = LabConfig(
            data_dir=Path(tmp),
            rigs=(RigConfig("twin", "Twin", "sim"), RigConfig("other", "Other", "sim")),
            database_url=url,
        )
        lab = Lab(config, clock=clock, database=Database(url))
        lab.start()
        try:
            t0 = time.perf_counter()
            build(lab, args.students, args.runs, args.trajectory)
            built = time.perf_counter() - t0
            clock.advance(timedelta(minutes=10 * (args.runs * args.students + 1)).total_seconds())
            end = clock.now()
            ours, peer = [], []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                data = lab.analytics.course("big")
                ours.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                loop = orm_loop(lab, end)
                peer.append(time.perf_counter() - t0)
            for s in data.students:
                seconds, runs = loop[s.username]
                assert abs(s.control_seconds - seconds) < 1e-2, (
                    s.username,
                    s.control_seconds,
                    seconds,
                )
                assert s.run_count == runs
            backend = "PostgreSQL" if schema else "SQLite"
            rows = args.students * args.runs
            print(
                f"{backend}: {args.students} students x {args.runs} runs ({rows} runs, "
                f"{2 * rows} results of {args.trajectory}-sample trajectories; "
                f"built in {built:.1f} s)"
            )
            print(f"  AnalyticsService.course  best {min(ours) * 1e3:8.1f} ms")
            print(f"  per-student ORM loop     best {min(peer) * 1e3:8.1f} ms")
            print(f"  ratio loop/ours          {min(peer) / min(ours):8.1f}x")
        finally:
            lab.close()
            if schema:
                with admin.connect() as c:
                    c.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
                admin.dispose()


if __name__ == "__main__":
    main()
