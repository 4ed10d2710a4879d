"""The command line's own words, in the user's language (``LANG=pt_BR.UTF-8``, ``LANGUAGE=es``).

Every line a person reads from ``serve``'s start, the first-start message and the
``user`` and ``course`` commands is declared here once, in English, as a gettext
msgid: the lab's catalogues (``thermolab/lab/locale``) translate it, and a word
without a translation stays English. What the lines name (commands, paths, file
names, user names) is never translated: a command printed in Portuguese still works
as printed.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

__all__ = ["CLI_WORDS", "cli_language", "say"]

#: key -> English msgid; ``{name}`` and the like are filled by :func:`say`.
CLI_WORDS: Mapping[str, str] = {
    # serve, as it starts
    "serve.on": "ThermoLab on {url}",
    "serve.database": "database: {url}",
    "serve.rigs": "rigs: {rigs}",
    "serve.speedups": "twin speed-ups: {paces}",
    "serve.speedups_given": "twin speed-ups (--speedup): {paces}",
    "serve.rig_warning": "warning: rig {rig}: {fault}",
    # the first start, while the lab has no teacher
    "first.no_teacher": (
        "No teacher account yet. In another terminal, create the lab's administrator"
    ),
    "first.admin_is": (
        "(a teacher who also manages accounts and rigs), then log in at the address above:"
    ),
    "first.a_teacher": "a teacher:",
    "first.students": ("students: a course, then its class list (a CSV with username,display_name"),
    "first.passwords": "columns; the one-time passwords go to passwords.csv, to hand out):",
    "first.one_student": "or one student:",
    "first.on_the_page": "(a teacher can also do this on a course's page once logged in.)",
    # accounts
    "user.password_for": "Password for {name}: ",
    "user.repeat": "Repeat the password: ",
    "user.differ": "the two passwords differ; nothing was changed",
    "user.no_stdin_password": "no password on standard input (expected one line)",
    "user.not_a_terminal": (
        "standard input is not a terminal, so the password cannot be asked: "
        "pipe it with --password-stdin"
    ),
    "user.added": "added {kind} {name}{shown}",
    "user.now_admin": "{name} is now a lab administrator",
    "user.no_longer_admin": "{name} is no longer a lab administrator",
    "user.none": "no accounts yet; add the lab's administrator with: {command}",
    "user.column_name": "username",
    "user.column_role": "role",
    "user.column_created": "created (UTC)",
    "user.password_changed": "changed the password of {name}; their logins have ended",
    "user.removed": "removed {kind} {name}",
    "user.forgot_kept": "forgot {name}: their runs kept as {pseudonym}",
    "user.forgot_deleted": "forgot {name}: their runs deleted",
    "role.admin": "admin",
    "role.teacher": "teacher",
    "role.student": "student",
    "private": "warning: tightened permissions of {path} to this user only",
    # courses
    "course.created": "created course {name} ({title}); enrolment code {code}",
    "course.none": "no courses yet; create one with: {command}",
    "course.all_rigs": "all rigs",
    "course.cannot_read": "cannot read {path}: {reason}",
    "course.imported": (
        "{course}: {created} created, {updated} updated, {unchanged} unchanged (read as {encoding})"
    ),
    "course.one_time_passwords": (
        "one-time passwords (shown once; each must be changed at first login):"
    ),
    "course.assists": "{name} assists course {course}",
    "course.no_longer_assists": "{name} no longer assists course {course}",
    # the command line itself
    "interrupted": "interrupted",
}


def cli_language() -> str:
    """The language of this process's user, from the POSIX locale variables."""
    from thermolab.lab.error_messages import language_from_environment

    return language_from_environment(os.environ)


def say(key: str, language: str | None = None, **values: object) -> str:
    """The words of ``key`` in ``language`` (default: the user's), ``values`` filled in.

    Examples
    --------
    >>> say("user.removed", "pt-BR", kind=say("role.student", "pt-BR"), name="'ana'")
    "conta removida: estudante 'ana'"
    >>> say("user.removed", "en", kind=say("role.student", "en"), name="'ana'")
    "removed student 'ana'"
    """
    from thermolab.lab.error_messages import translate

    return translate(CLI_WORDS[key], language or cli_language()).format(**values)
