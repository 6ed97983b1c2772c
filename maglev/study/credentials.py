"""Credentials in a tracking URI never reach a run, a report or the console.

``tracking.uri=http://user:password@host:5000`` would be stored in a param, the runs' tags
(``hydra.overrides``), the run description, the report and the config artifacts, and
printed.  The study strips the user and password from the URI as soon as it reads it
(:func:`public`), and hands them to MLflow through its own variables,
``MLFLOW_TRACKING_USERNAME`` and ``MLFLOW_TRACKING_PASSWORD`` (:func:`to_env`) — the way
to give them in the first place (docs/faults.md).  Text that may hold a URI (Hydra's
override list, its config files) is passed through :func:`redact` before it is logged.
"""

from __future__ import annotations

import logging
import os
import re
from urllib.parse import unquote, urlsplit, urlunsplit

USER_ENV, PASSWORD_ENV = "MLFLOW_TRACKING_USERNAME", "MLFLOW_TRACKING_PASSWORD"
# scheme://user[:password]@ in any text (a URI's userinfo), also as Hydra escapes it in overrides (http\://)
_USERINFO = re.compile(r"(?P<scheme>\b[A-Za-z][A-Za-z0-9+.-]*\\?://)[^\s/@'\"]+@")


def public(uri: str) -> str:
    """``uri`` without its user and password."""
    parts = urlsplit(uri)
    if "@" not in parts.netloc:
        return uri
    return urlunsplit(parts._replace(netloc=parts.netloc.rsplit("@", 1)[1]))


def to_env(uri: str) -> str:
    """Move the user and password of an HTTP(S) ``uri`` to MLflow's variables (unless they are set
    already) and return the URI without them."""
    parts = urlsplit(uri)
    if parts.scheme in ("http", "https") and parts.username is not None:
        os.environ.setdefault(USER_ENV, unquote(parts.username))
        if parts.password is not None:
            os.environ.setdefault(PASSWORD_ENV, unquote(parts.password))
    return public(uri)


def redact(text: str) -> str:
    """``text`` with the userinfo of every URI in it removed."""
    return _USERINFO.sub(r"\g<scheme>", text)


def redact_logs() -> None:
    """Redact every log record of this process from now on (Hydra's launchers log each job's overrides).
    A record factory, not a handler's filter: Hydra replaces the handlers for every job."""
    make = logging.getLogRecordFactory()
    if getattr(make, "redacts", False):
        return

    def redacting(*args, **kwargs) -> logging.LogRecord:
        record = make(*args, **kwargs)
        try:
            message = record.getMessage()
        except Exception:  # noqa: BLE001 — a malformed record is logging's to report
            return record
        if "@" in message:
            record.msg, record.args = redact(message), None
        return record

    redacting.redacts = True
    logging.setLogRecordFactory(redacting)
