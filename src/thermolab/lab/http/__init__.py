"""The lab's HTTP side: the app factory, one router per resource, schemas, the live socket.

* :mod:`.app` — :func:`create_app` (lifespan, sweeps, middleware);
* :mod:`.routers` — ``session``, ``rigs``, ``runs`` (with a run's bodies, built from
  the method registry), ``methods``, ``users``...;
* :mod:`.deps` — the lab and the logged-in user as route dependencies;
* request and answer bodies (pydantic, camelCase; base models in :mod:`.bodies`):
  :mod:`.error_schemas` (refusals), :mod:`.account_schemas` (logins, users),
  :mod:`.schemas` (a rig, its input and turns), :mod:`.control_schemas`
  (the closed loop), :mod:`.script_schemas` (tokens, readings);
* :mod:`.errors` — each error class's HTTP status and stable code;
* :mod:`.limits` — the request size limit;
* :mod:`.live_socket` — the WebSocket endpoint ``/api/rigs/{rig}/live``;
* :mod:`.live_logins` — its connections closed when their login or API token ends;
* :mod:`.live_messages` — its messages, typed, and what a client may send
  (:func:`~.live_messages.client_message_type`).
"""
