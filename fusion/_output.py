"""Output paths that never destroy anything, and atomic writes.

Standard library only, so that the command line can check its outputs before importing any
numerical library. :mod:`fusion.io` re-exports :func:`atomic_output`; every writer of the project
goes through it.

Rules (the command line applies the same ones before any work, see :mod:`fusion.cli`):

- a write is atomic: the file is written beside the destination under a temporary name and
  renamed onto it, so an interrupted or failed run never leaves a half-written result, and an
  existing result is replaced only by a complete one;
- a symbolic link is written through: its target is replaced, the link stays a link;
- a folder, a FIFO, a device (``/dev/null``, ``/dev/full``, ``/dev/stdout`` on a pipe or a
  terminal) or a socket is refused with a ValueError -- use ``"-"`` for standard output;
- ``"-"`` means standard output: the file is written to a private temporary folder and copied to
  stdout when complete;
- temporaries of runs that were killed (even by SIGKILL) are removed by the next write of the same
  destination; new files get the usual permissions (``0o666`` less the umask);
- folders created for an output are removed again when the write fails (if still empty);
- an OSError while writing (``[Errno 28] No space left on device``) names the destination file;
- inside :func:`outputs_together`, every write is committed at the end of the block, all or none.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["STDOUT", "TMP_MARK", "Terminated", "atomic_output", "atomic_outputs", "output_lock",
           "output_destination", "outputs_together", "private_folder", "special_file_kind",
           "termination_as_interrupt"]

logger = logging.getLogger(__name__)

PathLike = str | os.PathLike[str]

#: An output path of ``"-"`` means standard output (see :func:`atomic_output`).
STDOUT = "-"

#: Marker in the names of temporary files: ``.{name}.{pid}.fusion-tmp{suffix}`` beside `name`.
TMP_MARK = "fusion-tmp"

_SPECIAL_KINDS = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def special_file_kind(mode: int) -> str | None:
    """What a non-regular, non-folder file of ``st_mode`` `mode` is (``None`` for files, folders)."""
    for test, kind in _SPECIAL_KINDS:
        if test(mode):
            return kind
    return None


def output_destination(path: PathLike) -> Path:
    """The file an output to `path` replaces: `path` itself, or the target of a symbolic link.

    Writing through a link keeps the link a link and replaces its target (a dangling link gets a
    new target file). Raises ValueError if `path` is a folder, a symbolic-link loop, or a special
    file (FIFO, device, socket) -- ``/dev/null``, ``/dev/full`` and ``/dev/stdout`` on a pipe or
    terminal among them: an atomic write would replace the device node, or could not be done.
    """
    p = Path(path)
    try:
        st = os.stat(p)  # follows links
    except FileNotFoundError:
        st = None
    except OSError as e:  # ELOOP, ENAMETOOLONG, ...
        raise ValueError(f"{p}: cannot be written ({e.strerror})") from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise ValueError(f"{p}: is a folder, expected a file name")
        kind = special_file_kind(st.st_mode)
        if kind is not None:
            raise ValueError(f"{p}: is {kind}, not a regular file; refusing to write to it")
    if p.is_symlink():
        return Path(os.path.realpath(p))
    return p


def _pid_alive(pid: int) -> bool:
    """Whether process `pid` exists (on systems without signals, assume it does)."""
    if os.name != "posix":
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: alive, another user's
        return True
    return True


def _remove_stale_temporaries(dest: Path) -> None:
    """Delete temporary files of earlier writes of `dest` whose writing process is gone.

    Only names of the form ``.{name}.{pid}.fusion-tmp*`` are touched, and only when process
    ``pid`` no longer exists: a temporary of a live process (a concurrent run) is left alone.
    """
    prefix = f".{dest.name}."
    try:
        names = [e.name for e in os.scandir(dest.parent) if e.name.startswith(prefix)]
    except OSError:
        return
    for name in names:
        rest = name[len(prefix):]
        pid_text, _, tail = rest.partition(".")
        if (pid_text.isdigit() and tail.startswith(TMP_MARK) and int(pid_text) != os.getpid()
                and not _pid_alive(int(pid_text))):
            with contextlib.suppress(OSError):
                os.unlink(dest.parent / name)
                logger.info("removed stale temporary file %s", dest.parent / name)


def _copy_to_stdout(src: Path) -> None:
    sys.stdout.flush()
    buffer = getattr(sys.stdout, "buffer", None)
    with src.open("rb") as fh:
        if buffer is not None:
            shutil.copyfileobj(fh, buffer)
            buffer.flush()
        else:  # a text-only stream (some embedding environments)
            sys.stdout.write(fh.read().decode("utf-8", errors="replace"))
            sys.stdout.flush()


@contextlib.contextmanager
def atomic_output(path: PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success rename it onto `path`, else delete it.

    Parameters
    ----------
    path : path-like
        Final destination. Its folder is created if missing. A symbolic link is written through
        (its target is replaced, the link stays). ``"-"`` (:data:`STDOUT`) means standard output:
        the file is written to a private temporary folder and copied to stdout on success.
    suffix : str, optional
        Suffix of the temporary file (defaults to that of `path`, so that writers that pick a
        format by suffix, like soundfile, see the right one).

    Yields
    ------
    pathlib.Path
        Where to write.

    Raises
    ------
    ValueError
        `path` is a folder, a special file (FIFO, device, socket) or a symbolic-link loop.

    Notes
    -----
    The temporary file is ``.{name}.{pid}.fusion-tmp{suffix}`` in the destination's folder, with
    the usual permissions of a new file (those the umask allows). A run killed mid-write (even
    by SIGKILL) leaves it behind; the next write of the same destination removes temporaries
    whose process is gone, so they never pile up. Temporaries of live processes are kept, so
    two runs writing the same output at once do not delete each other's work.
    """
    sfx_default = Path(os.fspath(path)).suffix
    sfx = sfx_default if suffix is None else suffix
    if os.fspath(path) == STDOUT:
        with private_folder("fusion-stdout-") as folder:
            tmp = folder / f"stdout{sfx}"
            yield tmp
            _copy_to_stdout(tmp)
        return
    dest = output_destination(path)
    batch = _batch.get()
    created = _missing_folders(dest.parent)
    tmp = dest.parent / f".{dest.name}.{os.getpid()}.{TMP_MARK}{sfx}"
    try:
        with _naming(dest, tmp):
            if batch is not None:
                batch.folders += created
            dest.parent.mkdir(parents=True, exist_ok=True)
            _remove_stale_temporaries(dest)
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            # O_EXCL: never write through a link planted at the temporary name; 0o666 & ~umask.
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            yield tmp
            if batch is None:
                os.replace(tmp, dest)
            else:
                batch.renames.pop(dest, None)
                batch.renames[dest] = tmp  # committed with the others at the end of the block
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if batch is None:
            _remove_empty(created)
        raise


def _missing_folders(folder: PathLike) -> list[Path]:
    """`folder` and its ancestors that do not exist yet (outermost first)."""
    missing: list[Path] = []
    p = Path(os.path.abspath(folder))
    while not os.path.lexists(p) and p != p.parent:
        missing.insert(0, p)
        p = p.parent
    return missing


def _remove_empty(folders: list[Path]) -> None:
    """Remove those of `folders` that are empty, deepest first (created for a failed write)."""
    for f in sorted(set(folders), key=lambda q: len(q.parts), reverse=True):
        with contextlib.suppress(OSError):
            f.rmdir()


@contextlib.contextmanager
def _naming(dest: Path, tmp: Path) -> Iterator[None]:
    """OSErrors of writing `dest` name `dest` (``out.csv: No space left on device``).

    Writers report a full disk as ``[Errno 28] No space left on device`` without a file name,
    or with the temporary's; errors naming another file (an input read meanwhile) are kept.
    """
    try:
        yield
    except OSError as e:
        if e.filename is None or os.fspath(e.filename) == os.fspath(tmp):
            raise OSError(e.errno, e.strerror or str(e), os.fspath(dest)) from e
        raise


class _Batch:
    """Writes held by :func:`outputs_together`: destination -> temporary, created folders."""

    def __init__(self) -> None:
        self.renames: dict[Path, Path] = {}
        self.folders: list[Path] = []

    def commit(self) -> None:
        pending = list(self.renames.items())
        try:
            while pending:
                dest, tmp = pending[0]
                with _naming(dest, tmp):
                    os.replace(tmp, dest)
                pending.pop(0)
        finally:
            self.renames = dict(pending)

    def discard(self) -> None:
        for tmp in self.renames.values():
            with contextlib.suppress(OSError):
                tmp.unlink()
        self.renames.clear()
        _remove_empty(self.folders)


_batch: contextvars.ContextVar[_Batch | None] = contextvars.ContextVar("fusion_outputs",
                                                                       default=None)


@contextlib.contextmanager
def outputs_together(*folders: PathLike) -> Iterator[None]:
    """Every output written in the block (by :func:`atomic_output`) is committed at its end.

    A run that writes several files (a folder of figures, a simulated scenario, the files of
    several imported scenarios) writes each into its temporary; only when the block ends
    without an exception are they all renamed onto their names, in the order written. If the
    block fails (bad input found late, a full disk, Ctrl-C), every temporary is deleted, no
    output is replaced, and the folders created for the outputs -- those of `folders` (the
    ``--out`` folder) that did not exist when the block began, and those made by the writes --
    are removed when empty. Inside an enclosing block, this one joins it (commits at its end).

    A write inside the block is not readable under its name before the block ends.
    """
    if _batch.get() is not None:
        yield
        return
    batch = _Batch()
    for f in folders:
        if os.fspath(f) != STDOUT:
            batch.folders += _missing_folders(f)
    token = _batch.set(batch)
    try:
        yield
    except BaseException:
        _batch.reset(token)
        batch.discard()
        raise
    _batch.reset(token)
    try:
        batch.commit()
    except BaseException:
        batch.discard()
        raise


@contextlib.contextmanager
def atomic_outputs(*paths: PathLike, suffixes: tuple[str | None, ...] = ()) -> Iterator[list[Path]]:
    """Several outputs written together: temporaries, renamed onto their paths only at the end.

    Like :func:`atomic_output` for each of `paths` (`suffixes`: theirs, one per path, default
    each path's own): if writing any of them fails, none is replaced -- no result is left half
    written beside a missing other half (an :func:`outputs_together` block of its own, or the
    enclosing one).
    """
    if len(suffixes) > len(paths):
        raise ValueError(f"{len(suffixes)} suffixes for {len(paths)} paths")
    sfx = list(suffixes) + [None] * (len(paths) - len(suffixes))
    with outputs_together(), contextlib.ExitStack() as stack:
        yield [stack.enter_context(atomic_output(p, suffix=s))
               for p, s in zip(paths, sfx, strict=True)]


# --------------------------------------------------------------------------------------------
# private temporary folders, one writer per output, termination signals
# --------------------------------------------------------------------------------------------
def _remove_stale_folders(prefix: str) -> None:
    """Delete ``{tmp}/{prefix}{pid}-*`` folders whose process ``pid`` is gone (killed runs)."""
    root = Path(tempfile.gettempdir())
    try:
        names = [e.name for e in os.scandir(root) if e.name.startswith(prefix) and e.is_dir()]
    except OSError:
        return
    for name in names:
        pid_text = name[len(prefix):].partition("-")[0]
        if pid_text.isdigit() and int(pid_text) != os.getpid() and not _pid_alive(int(pid_text)):
            shutil.rmtree(root / name, ignore_errors=True)
            logger.info("removed the temporary folder %s of a run that was killed", root / name)


@contextlib.contextmanager
def private_folder(prefix: str) -> Iterator[Path]:
    """A private temporary folder ``{tmp}/{prefix}{pid}-XXXX``, removed at the end.

    A run killed by SIGKILL cannot remove its folder; the next run of any command using the
    same `prefix` removes the folders whose process is gone (never those of live runs).
    """
    _remove_stale_folders(prefix)
    with tempfile.TemporaryDirectory(prefix=f"{prefix}{os.getpid()}-") as folder:
        yield Path(folder)


def lock_path(path: PathLike) -> Path:
    """The lock file of an output: ``.{name}.fusion-lock`` beside it."""
    dest = output_destination(path) if not os.path.isdir(path) else Path(path)
    dest = Path(os.path.abspath(dest))
    return dest.parent / f".{dest.name}.fusion-lock"


@contextlib.contextmanager
def output_lock(path: PathLike) -> Iterator[None]:
    """Hold the lock of output `path` (nothing for ``"-"``): one run writes an output at a time.

    The lock file ``.{name}.fusion-lock`` beside the output holds the writer's process id and
    an exclusive ``flock``. The system releases a lock when its process ends, however it ends,
    so the lock of a killed run (even by SIGKILL) is taken over by the next run.

    Raises
    ------
    ValueError
        Another live run holds the lock: ``out.json: another fusion run (process 123) is
        writing this output; wait for it to finish or stop it``.
    """
    try:
        import fcntl
    except ImportError:  # no flock (Windows): no lock
        fcntl = None
    if os.fspath(path) == STDOUT or fcntl is None:
        yield
        return
    lock = lock_path(path)
    lock.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            owner = os.read(fd, 32).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            raise ValueError(f"{path}: another fusion run (process {owner}) is writing this "
                             f"output; wait for it to finish or stop it (lock {lock})") from None
        try:  # the file may have been removed by its last holder between open and flock
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)  # releases the flock


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: handled like Ctrl-C (temporaries removed, exit 128 + signal)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def termination_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (a KeyboardInterrupt).

    Every ``finally`` and context manager then runs as on Ctrl-C: temporaries of
    :func:`atomic_output` and :func:`private_folder` are removed. Only in the main thread;
    handlers are restored after the block.
    """
    import signal
    import threading

    wanted = [getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n)]
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _raise_terminated) for s in wanted}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
