"""The lab service: shared rigs, turns at the controls, runs, and their HTTP/WebSocket API.

* :mod:`.config` — what the lab serves (model, TOML reader, rig kinds);
* :mod:`.db` — rows, engine, Alembic migrations;
* :mod:`.users`, :mod:`.login_sessions`, :mod:`.security` — accounts, logins, throttling;
* :mod:`.access` — turn rules (one transition table), queries, views, the locked
  transaction, the actions;
* :mod:`.runs` — request (with its operating point), timing, statistics, store,
  export, ending, reading, service;
* :mod:`.devices` — :class:`~thermolab.lab.devices.DeviceHub`, the live rigs;
* :mod:`.fanout` — the live stream's per-rig channels;
* :mod:`.service` — :class:`~thermolab.lab.service.Lab`, everything wired together;
* :mod:`.http` — the app factory, routers, schemas, errors and the live socket.
"""
