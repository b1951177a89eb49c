"""Calls that need a deep C stack: GTSAM solves of long chain graphs.

GTSAM eliminates a chain graph (a track's states one after the other) into a Bayes tree one
clique deep per state, and walks and frees that tree recursively: on the main thread's 8 MiB
stack a chain of about 60,000 states (a smoothed track of 100,000 rows) ends the process with a
segmentation fault. :func:`with_deep_stack` runs such a call on a thread with a 1 GiB stack
(address space reserved, memory used only as deep as the recursion goes), which holds chains of
millions of states. The result is the same as in place: same code, same order of operations.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ["DEEP_STACK_BYTES", "with_deep_stack"]

T = TypeVar("T")

#: Stack of the thread of :func:`with_deep_stack`, bytes.
DEEP_STACK_BYTES = 1 << 30


def with_deep_stack(fn: Callable[..., T], /, *args, **kwargs) -> T:
    """``fn(*args, **kwargs)`` on a thread with a :data:`DEEP_STACK_BYTES` stack; its result,
    or its exception raised here.

    >>> with_deep_stack(sum, [1, 2, 3])
    6
    """
    result: list[T] = []
    error: list[BaseException] = []

    def target() -> None:
        try:
            result.append(fn(*args, **kwargs))
        except BaseException as e:  # handed to the caller's thread
            error.append(e)

    old = threading.stack_size(DEEP_STACK_BYTES)
    try:
        # daemon: Ctrl-C or SIGTERM in the caller ends the process without waiting for the solve
        thread = threading.Thread(target=target, name="fusion-deep-stack", daemon=True)
        thread.start()
    finally:
        threading.stack_size(old)
    thread.join()
    if error:
        raise error[0]
    return result[0]
