"""Structured logs: one JSON object per line on stderr.

Log calls pass their fields as ``extra={"fields": {...}}``; :class:`JsonLineFormatter` writes them
beside the time, level, logger and message.
"""

from __future__ import annotations

import json
import logging
import sys
import time

__all__ = ["JsonLineFormatter", "configure_json_logging", "uvicorn_log_config"]


class JsonLineFormatter(logging.Formatter):
    """Format a record as one JSON line: ``{"ts", "level", "logger", "msg", **fields}``."""

    def format(self, record: logging.LogRecord) -> str:
        line = {
            "ts": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(record.created))
            + f".{int(record.msecs):03d}Z",
            "level": record.levelname.lower(),
            "logger": record.name,
            "msg": record.getMessage(),
        }
        fields = getattr(record, "fields", None)
        if isinstance(fields, dict):
            line.update(fields)
        if record.exc_info:
            line["exception"] = self.formatException(record.exc_info)
        return json.dumps(line, default=str)


def configure_json_logging(level: str = "INFO") -> None:
    """Send the ``doorloc`` loggers to stderr as JSON lines (called once by ``doorloc serve``)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(JsonLineFormatter())
    logger = logging.getLogger("doorloc")
    logger.handlers[:] = [handler]
    logger.setLevel(level.upper())
    logger.propagate = False


def uvicorn_log_config(level: str = "INFO") -> dict:
    """A ``logging.config.dictConfig`` for uvicorn that writes its own lines (start-up, errors) as the same
    JSON lines as doorloc's, so one log holds one format."""
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "formatters": {"json": {"()": JsonLineFormatter}},
        "handlers": {
            "stderr": {"class": "logging.StreamHandler", "formatter": "json", "stream": "ext://sys.stderr"}
        },
        "loggers": {
            name: {"handlers": ["stderr"], "level": level.upper(), "propagate": False}
            for name in ("uvicorn", "uvicorn.error", "uvicorn.access")
        },
    }
