"""Accounts, password hashes, login sessions and the login throttle."""

from __future__ import annotations

import pytest
from argon2 import PasswordHasher
from sqlalchemy import select

from thermolab.errors import ConflictError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.security import (
    AuthenticationError,
    LoginThrottle,
    RateLimitedError,
    hash_token,
)
from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import ManualClock
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.models import Role, User
from thermolab.lab.service import Lab

from .conftest import PASSWORD


def test_accounts_are_created_listed_and_removed(lab: Lab) -> None:
    ana = lab.users.add("Ana", PASSWORD, "student")
    lab.users.add("tina", PASSWORD, Role.TEACHER)
    assert (ana.username, ana.role) == ("ana", Role.STUDENT)
    assert [(u.username, u.role.value) for u in lab.users.list()] == [
        ("ana", "student"),
        ("tina", "teacher"),
    ]
    assert lab.users.count_teachers() == 1
    assert lab.users.get("ANA").id == ana.id
    lab.users.remove("ana")
    with pytest.raises(NotFoundError, match="no user called 'ana'"):
        lab.users.get("ana")


@pytest.mark.parametrize(
    ("name", "password", "role", "error", "message"),
    [
        ("ana", PASSWORD, "admin", InvalidParameterError, "role 'admin' is not known"),
        ("a b", PASSWORD, "student", InvalidParameterError, "user name 'a b' is not valid"),
        ("", PASSWORD, "student", InvalidParameterError, "is not valid"),
        ("ana", "elevenchars", "student", InvalidParameterError, "at least 12 characters"),
        ("ana", " " * 12, "student", InvalidParameterError, "only whitespace"),
        ("ana", "password1234", "student", InvalidParameterError, "breached"),
        ("ana", "qwerty123456", "student", InvalidParameterError, "breached"),
        ("ana", "Dragon2024!!", "student", InvalidParameterError, "breached"),
        ("ana", "passwordpassword", "student", InvalidParameterError, "breached"),
        ("tina.lopez", "Tina.Lopez2024", "teacher", InvalidParameterError, "user name"),
        ("tina.lopez", "zepol.anit!!!", "teacher", InvalidParameterError, "user name"),
        ("anabel", "anabelanabel", "student", InvalidParameterError, "user name"),
        ("ana", "x" * 1025, "student", InvalidParameterError, "at most 1024"),
    ],
)
def test_bad_accounts_are_refused(
    lab: Lab, name: str, password: str, role: str, error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        lab.users.add(name, password, role)


def test_a_taken_name_is_a_conflict(lab: Lab) -> None:
    lab.users.add("ana", PASSWORD, "student")
    with pytest.raises(ConflictError, match="user 'ana' already exists"):
        lab.users.add("ANA", PASSWORD, "teacher")


def test_passwords_are_stored_as_argon2_hashes(lab: Lab) -> None:
    lab.users.add("ana", PASSWORD, "student")
    with lab.db.read() as session:
        stored = session.scalars(select(User.password_hash)).one()
    assert stored.startswith("$argon2id$")
    assert PASSWORD not in stored
    assert lab.users.verify("ana", PASSWORD).username == "ana"
    for name, password in [("ana", "wrong password"), ("nobody", PASSWORD), ("a b", PASSWORD)]:
        with pytest.raises(AuthenticationError, match="wrong user name or password"):
            lab.users.verify(name, password)


def test_weak_hashes_are_upgraded_at_login(lab: Lab) -> None:
    lab.users.add("ana", PASSWORD, "student")
    hasher = PasswordHasher(time_cost=2, memory_cost=16, parallelism=1)
    UserService(lab.db, lab.clock, hasher).verify("ana", PASSWORD)
    with lab.db.read() as session:
        stored = session.scalars(select(User.password_hash)).one()
    assert "m=16,t=2,p=1" in stored
    assert lab.users.verify("ana", PASSWORD).username == "ana"


def test_sessions_are_stored_hashed_and_expire(lab: Lab, clock: ManualClock) -> None:
    ana = lab.users.add("ana", PASSWORD, "student")
    token, principal = lab.sessions.create(ana, client_address="10.0.0.7", user_agent="test")
    assert len(token) >= 43
    with lab.db.read() as session:
        (stored,) = session.scalars(select(LoginSession.token_hash))
    assert stored == hash_token(token) != token
    assert lab.sessions.resolve(token) == principal
    assert lab.sessions.resolve("forged") is None
    assert lab.sessions.resolve(None) is None
    # Idle for the idle timeout (2 h): over.
    clock.advance(2 * 3600)
    assert lab.sessions.resolve(token) is None
    # Active all along, but past the lifetime (12 h): over too.
    token, _ = lab.sessions.create(ana)
    for _ in range(12):
        clock.advance(3600)
        alive = lab.sessions.resolve(token)
    assert alive is None
    assert lab.sessions.purge_expired() == 0  # expired sessions were deleted when seen


def test_changing_a_password_ends_the_other_logins(lab: Lab) -> None:
    ana = lab.users.add("ana", PASSWORD, "student")
    kept, principal = lab.sessions.create(ana)
    other, _ = lab.sessions.create(ana)
    lab.users.set_password("ana", "a new passphrase", keep_session=principal.session_id)
    assert lab.sessions.resolve(kept) is not None
    assert lab.sessions.resolve(other) is None
    lab.users.verify("ana", "a new passphrase")
    lab.users.set_password("ana", "yet another passphrase")
    assert lab.sessions.resolve(kept) is None


def test_removing_an_account_ends_its_sessions(lab: Lab) -> None:
    ana = lab.users.add("ana", PASSWORD, "student")
    token, _ = lab.sessions.create(ana)
    lab.remove_user("ana")
    assert lab.sessions.resolve(token) is None


def test_a_new_password_is_checked_against_the_name(lab: Lab) -> None:
    lab.users.add("ana", PASSWORD, "student")
    with pytest.raises(InvalidParameterError, match="user name") as info:
        lab.users.set_password("ana", "ANA-ana-ana-2024")
    assert "ANA-ana" not in str(info.value)  # the message never repeats the password
    lab.users.verify("ana", PASSWORD)


def test_failed_logins_delay_one_name_and_address_and_never_lock_out() -> None:
    clock = ManualClock()
    throttle = LoginThrottle(clock, failures_per_user=3, attempts_per_address=1000, window=60)
    waits = []
    for _ in range(12):
        while True:
            try:
                throttle.check("tina", "10.0.0.66")
                break
            except RateLimitedError as exc:
                waits.append(exc.retry_after)
                clock.advance(exc.retry_after)
        throttle.record("tina", "10.0.0.66", success=False)
    # Free failures, then doubling delays, capped at the window: never a lock-out.
    assert waits == [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 60.0, 60.0]
    with pytest.raises(RateLimitedError, match=r"'tina' from 10\.0\.0\.66; try again in 60 s"):
        throttle.check("tina", "10.0.0.66")
    # The teacher's own machine is not delayed by someone guessing elsewhere,
    throttle.check("tina", "10.0.0.5")
    throttle.record("tina", "10.0.0.5", success=True)
    # and the guesser's address gets in once the (bounded) delay has passed.
    clock.advance(60)
    throttle.check("tina", "10.0.0.66")
    throttle.record("tina", "10.0.0.66", success=True)  # a success clears the failures
    throttle.record("tina", "10.0.0.66", success=False)
    throttle.check("tina", "10.0.0.66")
    throttle.check("ben", "10.0.0.66")  # other names are not affected


def test_throttle_per_address() -> None:
    clock = ManualClock()
    throttle = LoginThrottle(clock, failures_per_user=100, attempts_per_address=5, window=60)
    for i in range(5):
        throttle.check(f"user{i}", "10.0.0.1")
        throttle.record(f"user{i}", "10.0.0.1", success=i % 2 == 0)
    with pytest.raises(RateLimitedError, match=r"from 10\.0\.0\.1; try again in 60 s"):
        throttle.check("someone", "10.0.0.1")
    throttle.check("someone", "10.0.0.2")
