"""The live stream: every rig's samples, estimates and access news, pushed to watchers.

* :mod:`.fanout` — per-rig channels, the replay buffer and each client's queue;
* :mod:`.frames` — WebSocket frames written straight to the connection;
* :mod:`.presence` — who watches which rig in this process;
* :mod:`.shared_presence` — the same, lab-wide across the workers of a fleet.

The protocol is ``docs/live-protocol.md``. Never touches the database in the
fan-out path: a message is encoded once and written to every socket.
"""
