"""Long runs at scale: independent tasks run serially or on Dask, finished parts kept on disk.

Three pieces any long command can share:

* :class:`PartStore` -- a folder of finished parts, one file per task, each written atomically
  (:func:`fusion._output.atomic_output`: a temporary file renamed onto its name), under a
  sub-folder named by a fingerprint of the run's inputs and options (:func:`fingerprint`). A run
  that is killed leaves the parts it finished; the same command run again finds them and
  computes only the rest. A changed command (another input file, a changed file, another
  option) has another fingerprint: its parts are never mixed with stale ones, which are removed.
* :func:`task_runner` -- where the tasks run: in this process, one after the other (the
  default), on ``workers`` local processes forked from this one (:class:`LocalPool`: they
  inherit its imported modules and the shared object, so they start in milliseconds), or on an
  existing Dask scheduler at ``scheduler`` (its workers must import this package and read the
  same paths; run them with one thread each, and preferably without Dask's default
  ``MALLOC_TRIM_THRESHOLD_``, which slows numpy-heavy tasks, see :func:`dask_client`).
  :func:`dask_client` starts a local Dask cluster instead (``LocalCluster``), for library users.
* :func:`run_tasks` -- runs the tasks that have no part yet, stores each result as it arrives
  (in any order) and reports progress; :func:`progress` is the progress bar of the project's
  long commands (a tqdm bar on a terminal, none when ``quiet`` or not a terminal).

Tasks are plain, picklable descriptions (paths and sample ranges, never audio); a task's result
must depend on its description and the shared object only, so that serial, parallel and resumed
runs store the same bytes.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar

from fusion._output import TMP_MARK, atomic_output
from fusion._progress import progress

__all__ = ["LocalPool", "PartStore", "dask_client", "file_identity", "fingerprint", "progress",
           "run_tasks", "task_runner"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


def fingerprint(obj: Any) -> str:
    """SHA-256 (hex) of `obj` written as canonical JSON (sorted keys; paths as strings)."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def file_identity(path: str | os.PathLike[str], *, content: bool = False) -> dict[str, Any]:
    """What identifies a file's version: absolute path, size, modification time (ns).

    With ``content=True`` the SHA-256 of its bytes instead of the time (for small files:
    models, arrays).
    """
    p = Path(path).resolve()
    st = p.stat()
    out: dict[str, Any] = {"path": str(p), "size": st.st_size}
    if content:
        out["sha256"] = hashlib.sha256(p.read_bytes()).hexdigest()
    else:
        out["mtime_ns"] = st.st_mtime_ns
    return out


class PartStore:
    """Finished parts of a run, one file each, in ``root/<key>/``.

    Parameters
    ----------
    root : path-like
        Folder of the parts (e.g. ``R.json.parts`` beside the output ``R.json``); created when
        the first part is written.
    key : str
        Fingerprint of the run's inputs and options (:func:`fingerprint`): only parts written
        under the same key are reused. Sub-folders of `root` with another key are stale and
        removed when the store is opened.
    """

    def __init__(self, root: str | os.PathLike[str], *, key: str) -> None:
        if not key or any(c in key for c in "/\\.") :
            raise ValueError(f"key must be a non-empty name without '/', '\\' or '.', got {key!r}")
        self.root = Path(root)
        self.key = key
        self.folder = self.root / key
        if self.root.exists() and not self.root.is_dir():
            raise ValueError(f"{self.root}: exists and is not a folder (it holds resume parts)")
        if self.root.is_dir():
            for stale in self.root.iterdir():
                if stale.name != key:
                    logger.info("removing parts of another run: %s", stale)
                    if stale.is_dir() and not stale.is_symlink():
                        shutil.rmtree(stale)
                    else:
                        stale.unlink()

    def names(self) -> set[str]:
        """Names of the finished parts."""
        if not self.folder.is_dir():
            return set()
        return {p.name for p in self.folder.iterdir() if TMP_MARK not in p.name}

    def write(self, name: str, text: str) -> None:
        """Store part `name` atomically (a reader sees the whole part or none)."""
        self._check(name)
        with atomic_output(self.folder / name) as tmp:
            tmp.write_text(text, encoding="utf-8")

    def read(self, name: str) -> str:
        """The text of part `name`."""
        self._check(name)
        return (self.folder / name).read_text(encoding="utf-8")

    def remove(self) -> None:
        """Delete the parts folder (after the final output is written)."""
        if self.root.is_dir():
            shutil.rmtree(self.root)

    @staticmethod
    def _check(name: str) -> None:
        if not name or "/" in name or "\\" in name or name.startswith("."):
            raise ValueError(f"part name must be a plain file name, got {name!r}")


@contextlib.contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """A Dask client for the run, or None to run in this process.

    Parameters
    ----------
    workers : int, optional
        Start a local cluster of this many worker processes, one thread each (closed on exit).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) to connect to instead.

    Yields
    ------
    distributed.Client or None
        None when neither is given (serial, the default).
    """
    if workers is not None and scheduler is not None:
        raise ValueError("give either workers (a local cluster) or a scheduler address, not both")
    if workers is None and scheduler is None:
        yield None
        return
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    from distributed import Client, LocalCluster

    quiet_dask = logging.getLogger("distributed")
    level = quiet_dask.level
    quiet_dask.setLevel(logging.ERROR)  # its start-up and shut-down chatter
    try:
        with _client(Client, LocalCluster, workers, scheduler) as client:
            yield client
    finally:
        quiet_dask.setLevel(level)


@contextlib.contextmanager
def _client(Client: Any, LocalCluster: Any, workers: int | None,
            scheduler: str | None) -> Iterator[Any]:
    """The client of :func:`dask_client` (Dask imported)."""
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as e:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler} ({e})") from None
        try:
            yield client
        finally:
            client.close()
        return
    import dask

    # workers are processes with one BLAS thread each (Dask's nanny sets it); no fixed ports.
    # The nanny's MALLOC_TRIM_THRESHOLD_ is left unset: any value turns off glibc's adaptive
    # mmap threshold, and every large temporary array is then mapped and faulted in anew
    # (measured: 2.5 times the CPU time per chunk of click localization).
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address="127.0.0.1:0",
                               silence_logs=logging.ERROR)
    try:
        with Client(cluster) as client:
            yield client
    finally:
        cluster.close()


class LocalPool:
    """``workers`` local processes forked from this one when :func:`run_tasks` starts.

    A forked worker inherits the modules this process imported and the shared object of the
    run (nothing is pickled but each task and its text result), so it starts in milliseconds;
    a local Dask cluster (:func:`dask_client`) spends seconds of CPU per worker on its
    scheduler, its nannies and the workers' imports (``benchmarks/RESULTS.md``, issue 17,
    second pass). Used on Linux, where ``fork`` is the usual start method; elsewhere (macOS,
    where system libraries are not fork-safe, and Windows) :func:`task_runner` falls back to a
    local Dask cluster.
    """

    def __init__(self, workers: int) -> None:
        if isinstance(workers, bool) or int(workers) != workers or workers < 1:
            raise ValueError(f"workers must be a positive integer, got {workers!r}")
        self.workers = int(workers)


@contextlib.contextmanager
def task_runner(*, workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """Where :func:`run_tasks` runs the tasks: None (this process, in order, the default), a
    :class:`LocalPool` of `workers` forked processes, or a Dask client of the scheduler at
    `scheduler` (:func:`dask_client`)."""
    import multiprocessing
    import sys

    if workers is not None and scheduler is None and sys.platform.startswith("linux") and (
            "fork" in multiprocessing.get_all_start_methods()):
        yield LocalPool(workers)
        return
    with dask_client(workers=workers, scheduler=scheduler) as client:
        yield client


#: The shared object of the run on a :class:`LocalPool`, read by its forked workers.
_INHERITED: list[Any] = []


def _inherited_call(fn: Callable[[Any, T], str], task: T) -> str:
    """``fn(shared, task)`` in a forked worker, with the shared object it inherited."""
    return fn(_INHERITED[0], task)


def _run_forked(fn: Callable[[Any, T], str], shared: Any, todo: Sequence[T], pool: LocalPool,
                done: Callable[[T, str], None]) -> None:
    """The tasks on `pool.workers` processes forked now; `done` with each result as it comes."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    if not todo:
        return
    _INHERITED[:] = [shared]  # before the fork: every worker inherits it
    ex = ProcessPoolExecutor(max_workers=min(pool.workers, len(todo)),
                             mp_context=multiprocessing.get_context("fork"))
    try:
        futures = {ex.submit(_inherited_call, fn, t): t for t in todo}
        while futures:
            finished, _ = wait(list(futures), return_when=FIRST_COMPLETED)
            for fut in finished:
                done(futures.pop(fut), fut.result())
    except BaseException:
        # a failed task, an interrupt or a signal: stop the workers now rather than wait for
        # their chunks (the parts already stored are kept for a resume)
        for proc in list((getattr(ex, "_processes", None) or {}).values()):
            proc.terminate()
        ex.shutdown(wait=False, cancel_futures=True)
        raise
    else:
        ex.shutdown(wait=True)
    finally:
        _INHERITED.clear()


def run_tasks(
    fn: Callable[[Any, T], str],
    shared: Any,
    tasks: Sequence[T],
    *,
    names: Callable[[T], str],
    store: PartStore,
    client: Any = None,
    on_done: Callable[[T], None] | None = None,
) -> None:
    """Run every task without a stored part; store each result as it is finished.

    Parameters
    ----------
    fn : callable
        ``fn(shared, task) -> str``: the part's text. Must be a module-level function (Dask
        pickles it by reference).
    shared : object
        Passed to every call (sent once to each worker on Dask).
    tasks : sequence
        Task descriptions (picklable).
    names : callable
        ``task -> part name``, unique.
    store : PartStore
        Where parts are kept; tasks whose part exists are skipped.
    client : LocalPool or distributed.Client, optional
        Run on forked local processes or on Dask (any order, as workers free up); default: in
        this process, in order.
    on_done : callable, optional
        Called with each task when its part is stored (also for the ones skipped, first).
    """
    have = store.names()
    todo = []
    for t in tasks:
        if names(t) in have:
            if on_done is not None:
                on_done(t)
        else:
            todo.append(t)
    if todo and len(todo) < len(tasks):
        logger.info("resuming: %d of %d parts already done", len(tasks) - len(todo), len(tasks))
    if client is None:
        for t in todo:
            store.write(names(t), fn(shared, t))
            if on_done is not None:
                on_done(t)
        return
    if isinstance(client, LocalPool):
        def done(t: T, text: str) -> None:
            store.write(names(t), text)
            if on_done is not None:
                on_done(t)

        _run_forked(fn, shared, todo, client, done)
        return
    from distributed import as_completed

    shared_f = client.scatter(shared, broadcast=True, hash=False)
    futures = {client.submit(fn, shared_f, t, pure=False): t for t in todo}
    try:
        for fut in as_completed(list(futures)):
            t = futures.pop(fut)
            text = fut.result()
            fut.release()
            store.write(names(t), text)
            if on_done is not None:
                on_done(t)
    finally:
        if futures:
            client.cancel(list(futures))
