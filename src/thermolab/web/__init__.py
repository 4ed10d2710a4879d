"""The browser interface: static files served by the lab service.

Everything the browser needs lives in :data:`STATIC_DIR`: ``index.html``, the
interface's plain ES modules (``js/``), its style sheet (``css/``) and the
vendored chart library (``vendor/uplot/``, with its licence). Nothing is built
and nothing is fetched from another site, so the lab works with no internet
access. The lab service does not import this package (layers go one way):
``thermolab serve`` hands :data:`STATIC_DIR` to
``thermolab.lab.create_app(config, static_dir=...)``.

Examples
--------
>>> from thermolab.web import STATIC_DIR
>>> (STATIC_DIR / "index.html").is_file()
True
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["STATIC_DIR"]

STATIC_DIR: Path = Path(__file__).resolve().parent / "static"
"""The folder to serve at ``/``: ``index.html``, ``js/``, ``css/`` and ``vendor/``."""
