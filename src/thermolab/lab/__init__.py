"""The lab service: shared rigs, turns at the controls, runs, and their HTTP/WebSocket API.

One folder per domain:

* :mod:`.config` — what the lab serves (model, TOML reader, rig kinds);
* :mod:`.db` — rows, engine, Alembic migrations;
* :mod:`.accounts` — users, logins, API tokens, passwords and the throttle;
* :mod:`.classes` — courses, class lists, per-course limits, bookings;
* :mod:`.assignments`, :mod:`.analytics`, :mod:`.guides` — set work, what was done, guide pages;
* :mod:`.access` — turn rules (one transition table), queries, views, the locked
  transaction, the actions;
* :mod:`.rigs` — :class:`~thermolab.lab.rigs.devices.DeviceHub`, rig settings, the camera;
* :mod:`.runs` — a run's request, store, statistics, export and service;
* :mod:`.agents` — rigs on a remote host (``thermolab agent``);
* :mod:`.live` — the live stream's per-rig channels and who watches;
* :mod:`.fleet` — several web workers: the lease, the bus, followers, takeover;
* :mod:`.lti` — LTI 1.3 launches, deep links, roster and grades;
* :mod:`.operations` — backups and restores, the log's format;
* :mod:`.audit` — the log of privileged actions (who did what to whom);
* :mod:`.http` — the app factory, routers, schemas, errors and the live socket.

At the top: :mod:`.service` (:class:`~thermolab.lab.service.Lab`, everything
wired together), with :mod:`.listener` (what it tells the live stream),
:mod:`.outcomes` (what its calls return) and :mod:`.rig_image` (a rig's live
image, camera or twin drawn), :mod:`.clock` (the injected clock), :mod:`.error_messages`
(the server's words in each language) and :mod:`.spreadsheets` (every CSV for
people in the reader's spreadsheet form; a leaf that analytics, assignments,
audit and runs share, worded through :mod:`.error_messages`, so no one domain
owns it).
"""
