"""Notes and warnings of a command, held until it ends: a failing run prints one line only.

:func:`held_notes` holds the ``WARNING`` (and higher) log records of the run and the Python
warnings raised in it (numpy's ``RuntimeWarning: overflow ...`` among them). When the command
succeeds they are printed, each as one line ``fusion CMD: warning: ...`` (a Python warning once
per message); when it fails they are dropped and its error line is the only line on stderr.
Records below ``WARNING`` (``-v``) are printed as they come.
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator


class _Hold(logging.Handler):
    """Keeps the records of at least WARNING; passes the others to `target` at once."""

    def __init__(self, target: logging.Handler) -> None:
        super().__init__(logging.NOTSET)
        self.target = target
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:
            self.records.append(record)
        else:
            self.target.handle(record)


@contextlib.contextmanager
def held_notes(handler: logging.Handler) -> Iterator[None]:
    """Hold the run's warnings (see the module notes); print them through `handler` on success."""
    root = logging.getLogger()
    hold = _Hold(handler)
    before = root.handlers[:]
    # the stream handlers (the command's stderr lines) are held; others (a test's) are kept
    root.handlers = [hold] + [h for h in before if type(h) is not logging.StreamHandler]
    ok = False
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            yield
            ok = True
    finally:
        root.handlers = before
        if ok:
            for record in hold.records:
                handler.handle(record)
            seen = set()
            for w in caught:
                text = " ".join(str(w.message).split())
                if text not in seen:
                    seen.add(text)
                    handler.handle(logging.makeLogRecord({
                        "name": "fusion", "levelno": logging.WARNING, "levelname": "WARNING",
                        "msg": f"{text} ({w.category.__name__})"}))
