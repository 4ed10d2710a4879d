"""Several web workers on one database: who owns the rigs and what travels between them.

* :mod:`.workers` — :class:`~.workers.Fleet` (the bus topics, owner announcements)
  and :func:`~.workers.start_worker`;
* :mod:`.follower` — a follower worker's lab and its promotion to owner (takeover);
* :mod:`.lease` — one owner per database: the lease row;
* :mod:`.bus` — the message bus (in-process, or Redis pub/sub);
* :mod:`.worker_hashes` — what each worker publishes about itself in Redis;
* :mod:`.shared_limits` — the login throttle and live-socket limits, lab-wide.

A lone ``thermolab serve`` uses only the lease and the in-process bus; Redis is
imported only when a broker is configured.
"""
