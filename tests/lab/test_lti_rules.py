"""Laws of the LTI tool's small rules, for every input (Hypothesis)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from thermolab.lab.db.models import MemberRole, Role
from thermolab.lab.lti.claims import course_role, lab_role
from thermolab.lab.lti.deep_linking import target_path
from thermolab.lab.lti.grades import retry_delay

_VOCAB = "http://purl.imsglobal.org/vocab/lis/v2/"
ROLE_NAMES = ["Instructor", "Administrator", "Learner", "Mentor", "TeachingAssistant", "Member"]
roles = st.lists(
    st.one_of(
        st.sampled_from(ROLE_NAMES).map(lambda r: f"{_VOCAB}membership#{r}"),
        st.sampled_from(ROLE_NAMES).map(lambda r: f"{_VOCAB}institution/person#{r}"),
        st.sampled_from(ROLE_NAMES),
        st.text(max_size=40),
        st.integers(),
        st.none(),
    ),
    max_size=6,
)


@given(roles)
def test_only_an_instructor_or_administrator_is_a_teacher(given_roles: list[object]) -> None:
    teaching = any(
        isinstance(r, str)
        and r.rsplit("#", 1)[-1].rsplit("/", 1)[-1] in ("Instructor", "Administrator")
        for r in given_roles
    )
    assert (lab_role(given_roles) is Role.TEACHER) == teaching


@given(roles)
def test_a_teaching_assistant_assists_unless_also_a_teacher(given_roles: list[object]) -> None:
    names = {r.rsplit("#", 1)[-1].rsplit("/", 1)[-1] for r in given_roles if isinstance(r, str)}
    expected = (
        MemberRole.TEACHER
        if names & {"Instructor", "Administrator"}
        else MemberRole.ASSISTANT
        if "TeachingAssistant" in names
        else MemberRole.STUDENT
    )
    assert course_role(given_roles) is expected


@given(st.one_of(st.text(max_size=300), st.none(), st.integers()))
def test_a_launched_target_never_leaves_the_labs_own_pages(target: object) -> None:
    # The target comes from the LMS's custom claim and becomes a redirect: it must stay
    # a fragment of the lab's own page, whatever it says ("//evil.example", "\\x", ...).
    path = target_path(target)
    assert path.startswith("/#/")
    assert "\n" not in path
    assert "\r" not in path


@given(st.integers(min_value=1, max_value=10_000))
def test_retries_wait_longer_each_time_up_to_an_hour(attempts: int) -> None:
    assert 30.0 <= retry_delay(attempts) <= 3600.0
    assert retry_delay(attempts + 1) >= retry_delay(attempts)
