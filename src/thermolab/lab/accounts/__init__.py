"""Accounts: who someone is, how they log in, and what they are called.

* :mod:`.users` — user accounts and roles (:class:`~.users.Principal`);
* :mod:`.policy` — who may do what, on which scope: the one table every route asks;
* :mod:`.login_sessions` — a password login into a server-side session;
* :mod:`.tokens` — personal API tokens for scripts and notebooks;
* :mod:`.security` — password hashing, session tokens, the login throttle;
* :mod:`.names`, :mod:`.name_book` — login names normalised, display names looked up;
* :mod:`.personal_data` — everything the lab holds about a person (export), and
  forgetting them (found by walking the schema).

Owns the ``users``, ``login_sessions`` and ``api_tokens`` rows. Imports nothing
from the rigs, runs or the live stream: an account knows no rig.
"""
