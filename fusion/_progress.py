"""The progress bar of the project's long commands.

A tqdm bar on standard error while it is a terminal; nothing when the command is given
``--quiet`` or its standard error is a file or a pipe (archives processed by scripts keep clean
logs). tqdm is imported only when a bar is shown, so short commands pay nothing for it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

__all__ = ["RowShare", "WindowProgress", "progress", "track_progress"]

T = TypeVar("T")


def progress(total: int | None, *, quiet: bool = False, desc: str = "", unit: str = "it",
             initial: int = 0) -> Any:
    """A tqdm progress bar on stderr when it is a terminal and not `quiet`, else a stand-in.

    Parameters
    ----------
    total : int or None
        Units of work in all; None when unknown (the bar then counts and shows the rate).
    quiet : bool
        No bar whatever the terminal.
    desc, unit : str
        The bar's label and the name of one unit.
    initial : int
        Units already done (a resumed run).

    Returns
    -------
    tqdm or stand-in
        Has ``update(n)`` and ``close()`` either way.
    """
    if quiet or not sys.stderr.isatty():
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit=unit, file=sys.stderr)


def track_progress(items: Iterable[T], *, quiet: bool = False, desc: str = "",
                   unit: str = "it", total: int | None = None,
                   weight: Any = None) -> Iterator[T]:
    """Yield `items` while a bar (see :func:`progress`) counts them; closed when they end.

    `weight(item)` gives the units one item stands for (e.g. the rows of a chunk); 1 when None.
    """
    bar = progress(total, quiet=quiet, desc=desc, unit=unit)
    try:
        for item in items:
            yield item
            bar.update(1 if weight is None else int(weight(item)))
    finally:
        bar.close()


class _NoBar:
    """What :func:`progress` returns when no bar is shown."""

    def update(self, n: int = 1) -> None:
        """Nothing to show."""

    def set_description(self, desc: str, refresh: bool = True) -> None:
        """Nothing to label."""

    def close(self) -> None:
        """Nothing to close."""


class RowShare:
    """Rows of work handed to a progress callback ``on_rows(n)`` in parts as the work goes on.

    `rows` in all, each handed out once: :meth:`half` hands out half of what is left (one
    solver iteration, of an unknown count), :meth:`upto` all but the part of the rows not yet
    done (a fraction of known work), :meth:`rest` what is left. With `on_rows` None nothing is
    called.

    >>> seen = []
    >>> share = RowShare(10, seen.append)
    >>> share.half(); share.upto(0.8); share.rest()
    >>> seen
    [5, 3, 2]
    """

    def __init__(self, rows: int, on_rows: Callable[[int], None] | None) -> None:
        self.rows = self.left = int(rows)
        self.on_rows = on_rows

    def give(self, n: int) -> None:
        """Hand out `n` more rows (at most those left)."""
        n = min(int(n), self.left)
        if n > 0:
            self.left -= n
            if self.on_rows is not None:
                self.on_rows(n)

    def half(self) -> None:
        """Hand out half of the rows left."""
        self.give(self.left // 2)

    def upto(self, fraction: float) -> None:
        """Hand out rows until `fraction` of all of them have been."""
        self.give(int(self.rows * fraction) - (self.rows - self.left))

    def rest(self) -> None:
        """Hand out every row left."""
        self.give(self.left)


class WindowProgress:
    """The bar of ``fusion localize``: windows localized, and the stage that runs.

    In this process the bar moves per window and names the stage (measuring: clicks, TDOAs,
    validation; localizing); on workers it moves per chunk as each part is stored.
    """

    def __init__(self, bar, *, in_process: bool) -> None:
        self.bar, self.counted = bar, 0
        self.bar.set_description("localize" if in_process else "localize (chunks on workers)")

    def window(self, stage: str) -> None:
        """One window passed `stage` (:func:`fusion.pipelines.clicks.chunks.chunk_windows`)."""
        if stage == "localizing":
            self.bar.set_description("localize: localizing", refresh=False)
            self.bar.update(1)
            self.counted += 1
        else:
            self.bar.set_description(f"localize: {stage}")

    def chunk_done(self, task) -> None:
        """A chunk's part is stored (or was, by an earlier run): its windows not yet counted."""
        self.bar.update(task.stop_window - task.first_window - self.counted)
        self.counted = 0
