"""Running the lab for a term: backups and restores, and the server's log format.

* :mod:`.backup` — ``thermolab backup`` / ``restore``: one archive (manifest,
  checksums) of the database and the data folder, restored into an empty one;
* :mod:`.logs` — the log as text or as JSON lines (``--log-format``);
* :mod:`.collector` — the garbage collector's full passes kept short while
  sockets join, everything collected when no run is going.

Health and metrics are served by :mod:`thermolab.lab.http.observe`. Nothing
here is on a request's path.
"""
