"""The server's log as JSON lines (``thermolab serve --log-format json``).

One object a line — ``time`` (UTC, ISO 8601), ``level``, ``logger``,
``message``, and ``exception`` when there is one — so that journald, Loki or
an ELK stack read it without a parser of their own. :func:`log_config` is
the ``logging.config.dictConfig`` that uvicorn is given: its own loggers
(``uvicorn.error``, ``uvicorn.access``) and the lab's go through it alike.

Examples
--------
>>> import json, logging
>>> record = logging.LogRecord("thermolab.lab", logging.WARNING, "x.py", 1, "rig %s down",
...                            ("twin",), None)
>>> record.created = 0.0
>>> json.loads(JsonLines().format(record))  # doctest: +NORMALIZE_WHITESPACE
{'time': '1970-01-01T00:00:00.000+00:00', 'level': 'warning', 'logger': 'thermolab.lab',
 'message': 'rig twin down'}
"""

from __future__ import annotations

import datetime as dt
import json
import logging
from typing import Any, Literal

__all__ = ["JsonLines", "LogFormat", "log_config"]

LogFormat = Literal["text", "json"]


class JsonLines(logging.Formatter):
    """A log record as one line of JSON."""

    def format(self, record: logging.LogRecord) -> str:
        """Return the record as a JSON object on one line."""
        data: dict[str, Any] = {
            "time": dt.datetime.fromtimestamp(record.created, dt.UTC).isoformat(
                timespec="milliseconds"
            ),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        if record.exc_info:
            data["exception"] = self.formatException(record.exc_info)
        return json.dumps(data, ensure_ascii=False)


def log_config(form: LogFormat, level: str = "INFO") -> dict[str, Any] | None:
    """The logging configuration for ``form`` (``None``: uvicorn's own, for text)."""
    if form == "text":
        return None
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "formatters": {"json": {"()": JsonLines}},
        "handlers": {
            "stderr": {
                "class": "logging.StreamHandler",
                "formatter": "json",
                "stream": "ext://sys.stderr",
            }
        },
        "root": {"handlers": ["stderr"], "level": level},
        "loggers": {
            "uvicorn": {"handlers": [], "propagate": True, "level": level},
            "uvicorn.error": {"handlers": [], "propagate": True, "level": level},
            "uvicorn.access": {"handlers": [], "propagate": True, "level": level},
        },
    }
