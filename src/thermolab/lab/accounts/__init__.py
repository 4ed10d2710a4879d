"""Accounts: who someone is, how they log in, and what they are called.

* :mod:`.users` — user accounts and roles (:class:`~.users.Principal`);
* :mod:`.login_sessions` — a password login into a server-side session;
* :mod:`.tokens` — personal API tokens for scripts and notebooks;
* :mod:`.security` — password hashing, session tokens, the login throttle;
* :mod:`.names`, :mod:`.name_book` — login names normalised, display names looked up.

Owns the ``users``, ``login_sessions`` and ``api_tokens`` rows. Imports nothing
from the rigs, runs or the live stream: an account knows no rig.
"""
