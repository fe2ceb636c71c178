"""How the data layer's warnings reach the user: through ``logging``, each at its level, each
said once per command.

The data layer warns through its module loggers, ``data_logger(__name__)``
(``log.warning("%s: no kinematics; trial skipped", ...)``). A command reads a release several
times (its layout, its users, its data, its fingerprint) and would repeat every warning as often:
those loggers let each message through once (``ONCE``), until ``new_command`` (which
``cli.common.run_command`` calls; in Python, once per process, as the ``warnings`` module does,
or call ``new_command`` yourself).

Python's last-resort handler prints a bare message when the application configures no logging;
the ``jigsaws_tools`` logger has a handler of its own (``install``) that prints ``WARNING:
message`` on standard error instead, only where no other handler receives the message: once the
application configures logging, its configuration decides (``cli.common.configure_output``: the
same format).
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path

PACKAGE_LOGGER = "jigsaws_tools"
FORMAT = "%(levelname)s: %(message)s"


class OnceFilter(logging.Filter):
    """Lets through a record whose logger, level and message have not passed since the last
    ``clear``."""

    def __init__(self):
        super().__init__()
        self._seen: set[tuple[str, int, str]] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        key = (record.name, record.levelno, record.getMessage())
        if key in self._seen:
            return False
        self._seen.add(key)
        return True

    def clear(self) -> None:
        self._seen.clear()


#: The filter of every data logger.
ONCE = OnceFilter()
#: The cache folders found unwritable in this command (``cache_unwritable``).
_UNWRITABLE: set[str] = set()


def data_logger(name: str) -> logging.Logger:
    """The logger ``name`` (a ``jigsaws_tools`` module's), saying each message once per command."""
    logger = logging.getLogger(name)
    if ONCE not in logger.filters:
        logger.addFilter(ONCE)
    return logger


def new_command() -> None:
    """Start a new command: every data warning may be said once more."""
    ONCE.clear()
    _UNWRITABLE.clear()


def cache_unwritable(cache_dir: Path | str, error: OSError, instead: str) -> None:
    """The one warning of a command that its cache folder ``cache_dir`` cannot be written
    (``error``), saying what is done ``instead``; later failures to write there (the synthetic
    release, then the preprocessed data) say nothing more."""
    if str(cache_dir) in _UNWRITABLE:
        return
    _UNWRITABLE.add(str(cache_dir))
    data_logger(f"{PACKAGE_LOGGER}.cache").warning(
        "cannot write the cache folder %s (%s); %s", cache_dir, error.strerror or error, instead)


class _UnconfiguredHandler(logging.Handler):
    """``LEVEL: message`` on standard error (the one of the moment, so that a redirection is
    followed) for records of WARNING and above that no other handler receives: where Python's
    last-resort handler would print the bare message."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.setFormatter(logging.Formatter(FORMAT))

    def emit(self, record: logging.LogRecord) -> None:
        if self._handled_elsewhere(logging.getLogger(record.name)):
            return
        try:
            sys.stderr.write(self.format(record) + "\n")
        except Exception:                       # as logging.StreamHandler does
            self.handleError(record)

    def _handled_elsewhere(self, logger: logging.Logger | None) -> bool:
        """A handler other than this one is on ``logger`` or on an ancestor it propagates to."""
        while logger is not None:
            if any(h is not self for h in logger.handlers):
                return True
            if not logger.propagate:
                return False
            logger = logger.parent
        return False


def install(name: str = PACKAGE_LOGGER) -> None:
    """Give the logger ``name`` (a package's: ``jigsaws_tools``, ``multitask``) its fallback
    handler, once per process."""
    logger = logging.getLogger(name)
    if not any(isinstance(h, _UnconfiguredHandler) for h in logger.handlers):
        logger.addHandler(_UnconfiguredHandler())
