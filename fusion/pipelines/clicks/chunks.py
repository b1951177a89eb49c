"""Click localization of a long recording in independent chunks of consecutive windows.

The processing windows of ``fusion localize`` (12 s every 2 s) overlap, and a window's TDOAs
are confirmed by its neighbours' (time association, eq. 12 of *Localization of Short Duration
Periodic Signals*). A chunk (:class:`ChunkTask`) is a run of consecutive windows, by default
60 s of them; its task reads, from the file(s) itself, the audio from a little before its first
window to a little after its last -- the margin of one window on each side (the neighbours the
association needs) plus the detector's guards -- measures those windows
(:meth:`ClickFrontEnd.measure`), associates them (:meth:`ClickFrontEnd.associate`) and
localizes its own (:meth:`ClickLocalization.localize`). Chunks therefore need nothing from each
other and run in any order, on any worker; their windows are stitched in order.

The stream of each chunk starts on the block grid of a stream from the start of the recording,
at a point where that stream makes its clicks final (:func:`fusion.pipelines.clicks.stream.
stream_start`), so every window is computed from the same samples, cut at the same places, as
in one pass over the whole recording: the result does not depend on the chunking, nor on where
the chunks ran. Each task works with one BLAS thread (the threads of a Dask worker), so that
serial and parallel runs share their arithmetic.

Per chunk the two neighbour windows are measured twice (once by each chunk that needs them):
2 of 32 windows at the default 60 s, about 6 % more work for chunks that are independent.

Examples
--------
The chunks of a recording, run here one after the other (``fusion localize`` hands the same
calls to :func:`fusion.scale.run_tasks`, on forked worker processes with ``--workers``)::

    from fusion.io import check_audio_files, read_array
    from fusion.pipelines.localization import ClickLocalization

    array = read_array("array.json")
    source = AudioSource.of(check_audio_files(["audio.flac"], array.n_sensors))
    # decided once, from the first minute (the chunks run the pipeline as given)
    first = source.start_samples(int(60 * source.fs))  # kept: the first chunk reuses it
    pipe, decided = ClickLocalization().with_recording_decisions(first, source.fs, array)
    parts = [localize_chunk((pipe, array), task) for task in plan_chunks(source, pipe)]
    document = DocumentText(parts)
    with open("result.json", "w", encoding="utf-8") as f:
        f.writelines(document)
    print(document.summary.line())
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fusion._validation import check_positive
from fusion.geometry import SensorArray
from fusion.pipelines.clicks.stream import stream_start, window_starts_count
from fusion.pipelines.localization import ClickLocalization, LocalizedWindow, result_document

__all__ = ["FEW_TDOAS", "AudioSource", "ChunkTask", "DocumentSummary", "DocumentText",
           "localize_chunk", "plan_chunks", "source_flags"]

#: The start of one recording read by :meth:`AudioSource.start_samples`: [(source, samples)].
_HELD: list[tuple[AudioSource, NDArray[np.float32]]] = []


@dataclass(frozen=True)
class AudioSource:
    """A recording on disk: one multichannel file, or one mono file per sensor.

    Attributes
    ----------
    paths : tuple of str
        Absolute paths; channel i is sensor i (one file), or file i is sensor i.
    fs : float
        Sample rate, Hz.
    frames : int
        Samples per channel (the shortest file's).
    """

    paths: tuple[str, ...]
    fs: float
    frames: int

    @property
    def duration_s(self) -> float:
        """Length, s."""
        return self.frames / self.fs

    @classmethod
    def of(cls, files) -> AudioSource:
        """The source of a recording whose files :func:`fusion.io.check_audio_files` checked.

        `files` gives ``paths``, ``fs`` and ``frames`` (the shortest file's length: longer files
        are read only that far). The checks themselves live in :mod:`fusion.io` alone.
        """
        return cls(tuple(str(Path(p).resolve()) for p in files.paths), float(files.fs),
                   int(files.frames))

    def start_samples(self, n: int) -> NDArray[np.float32]:
        """The first `n` samples (n, channels), float32, kept in this process for the next
        :meth:`blocks` that reads them (the first minute is read for the decisions and again
        by the first chunk: decoded once). One recording's start is kept at a time."""
        _, first = next(self.blocks(block=n))
        _HELD[:] = [(self, first)]
        return first

    def blocks(self, *, block: int, start: int = 0) -> Iterator[tuple[float, NDArray[np.float32]]]:
        """Consecutive blocks ``(t0, samples (n, channels))`` of `block` samples from `start`.

        The blocks lie on the grid ``[start + k block, ...)``; the last may be shorter. Read with
        soundfile as float32, never the whole file (blocks inside the start kept by
        :meth:`start_samples` are copied from it: the same samples, decoded once).
        """
        import soundfile as sf

        if block < 1 or not 0 <= start < self.frames:
            raise ValueError(f"block {block} must be >= 1 and start {start} in [0, {self.frames})")
        first = start
        held = next((x for src, x in _HELD if src == self), None)
        if held is not None:
            _HELD.clear()  # read once more at most
            while first < self.frames and (first + block <= held.shape[0]
                                           or held.shape[0] == self.frames):
                x = held[first:first + block].copy()
                yield first / self.fs, x
                first += x.shape[0]
            del held
            if first >= self.frames:
                return
        readers = [sf.blocks(p, blocksize=block, dtype="float32", always_2d=True, start=first,
                             stop=self.frames) for p in self.paths]
        try:
            for parts in zip(*readers, strict=True):
                x = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
                yield first / self.fs, x
                first += x.shape[0]
        except (RuntimeError, sf.LibsndfileError) as e:
            raise ValueError(f"{self.paths[0]}: audio could not be decoded near "
                             f"{first / self.fs:g} s ({e})") from None


@dataclass(frozen=True)
class ChunkTask:
    """One chunk: the recording, the windows it reports, the windows and audio it reads.

    A description only (paths and sample ranges): the task reads its audio itself.

    Attributes
    ----------
    source : AudioSource
        The recording.
    index : int
        Chunk number (0 first).
    first_window, stop_window : int
        It reports windows ``first_window <= k < stop_window``.
    measure_first, measure_stop : int
        It measures windows ``measure_first <= k < measure_stop``: its own and one neighbour
        on each side (where there is one).
    start_sample : int
        First sample it reads (on the grid of `block`).
    final_from : int
        Its clicks are final from this sample on.
    block : int
        Read block, samples (the hop).
    """

    source: AudioSource
    index: int
    first_window: int
    stop_window: int
    measure_first: int
    measure_stop: int
    start_sample: int
    final_from: int
    block: int

    @property
    def name(self) -> str:
        """File name of the chunk's part."""
        return f"chunk-{self.index:06d}.json"


def plan_chunks(
    source: AudioSource, pipe: ClickLocalization, *, chunk_s: float = 60.0
) -> tuple[ChunkTask, ...]:
    """Cut a recording's windows into chunks of about `chunk_s` of consecutive windows.

    Parameters
    ----------
    source : AudioSource
        The recording.
    pipe : ClickLocalization
        Its front end's window, hop and detector guard set the windows and margins.
    chunk_s : float, optional
        Audio per chunk, s: ``round(chunk_s / hop)`` windows (at least one).

    Returns
    -------
    tuple of ChunkTask
        In window order, covering every window once.
    """
    check_positive("chunk_s", chunk_s)
    front = pipe.front_end
    fs = source.fs
    n = window_starts_count(source.duration_s, front.window_s, front.hop_s)
    per = max(1, int(round(chunk_s / front.hop_s)))
    block = max(int(round(front.hop_s * fs)), 1)
    guard = int(math.ceil(front.detector.guard_s(fs) * fs))
    tasks = []
    for c, k0 in enumerate(range(0, n, per)):
        k1 = min(k0 + per, n)
        a, b = max(k0 - 1, 0), min(k1 + 1, n)
        start, final_from = stream_start(int(round(a * front.hop_s * fs)), block=block,
                                         guard=guard)
        tasks.append(ChunkTask(source, c, k0, k1, a, b, start, final_from, block))
    return tuple(tasks)


def chunk_windows(
    pipe: ClickLocalization, sensors: SensorArray, task: ChunkTask,
    on_window: Callable[[str], None] | None = None,
) -> list[LocalizedWindow]:
    """The localized windows of one chunk (read, detect, measure, associate, localize).

    `on_window(stage)` is called as each window passes a stage: ``"measuring"`` (clicks,
    TDOAs, validation; the chunk's neighbour windows too) and ``"localizing"`` (its own windows).
    """
    from threadpoolctl import threadpool_limits

    def told(windows: Iterable, stage: str) -> Iterator:
        for w in windows:
            yield w
            on_window(stage)

    front, source = pipe.front_end, task.source
    with threadpool_limits(1):
        measured = front.measure(source.blocks(block=task.block, start=task.start_sample),
                                 fs=source.fs, sensors=sensors, duration_s=source.duration_s,
                                 start_sample=task.start_sample, final_from=task.final_from,
                                 first_window=task.measure_first, stop_window=task.measure_stop)
        if on_window is not None:
            measured = told(measured, "measuring")
        windows = list(front.associate(measured))
        skip = task.first_window - task.measure_first
        own = windows[skip:skip + task.stop_window - task.first_window]
        if len(own) != task.stop_window - task.first_window:
            raise ValueError(f"chunk {task.index}: measured {len(windows)} windows, expected "
                             f"{task.measure_stop - task.measure_first}")
        if on_window is None:
            return [pipe.localize(w, sensors) for w in own]
        return list(told((pipe.localize(w, sensors) for w in own), "localizing"))


def localize_chunk(shared: tuple, task: ChunkTask) -> str:
    """One chunk's part: its windows in the ``fusion localize`` JSON, as one JSON list (text).

    Parameters
    ----------
    shared : (ClickLocalization, SensorArray) or (ClickLocalization, SensorArray, on_window)
        The pipeline and the array (the same for every chunk, of every recording); in this
        process also `on_window` of :func:`chunk_windows` (a progress report).
    task : ChunkTask
        The chunk.

    Returns
    -------
    str
        ``json.dumps`` of the chunk's ``windows`` entries (:func:`result_document`).
    """
    doc = result_document(chunk_windows(*shared, task) if len(shared) == 2 else
                          chunk_windows(shared[0], shared[1], task, on_window=shared[2]))
    return json.dumps(doc["windows"], allow_nan=False)


@dataclass(frozen=True)
class DocumentSummary:
    """What a :class:`DocumentText` held: windows, valid TDOAs and sources in all.

    Of the sources, `n_unobservable` are flagged unobservable, `n_mirror` mirror-ambiguous and
    `n_few_tdoas` rest on :data:`FEW_TDOAS` TDOAs or fewer (no redundancy to check the fix);
    a source may carry more than one flag, `n_flagged` counts each once.
    """

    n_windows: int
    n_valid_tdoas: int
    n_sources: int
    n_unobservable: int = 0
    n_mirror: int = 0
    n_few_tdoas: int = 0
    n_flagged: int = 0
    n_not_localized: int = 0
    not_localized_reason: str = ""

    def line(self) -> str:
        """The one-line summary ``fusion localize`` prints."""
        flags = [f"{n} {what}" for n, what in ((self.n_unobservable, "unobservable"),
                                               (self.n_mirror, "mirror-ambiguous"),
                                               (self.n_few_tdoas, f"on <= {FEW_TDOAS} TDOAs"))
                 if n]
        flagged = f" ({self.n_flagged} flagged: {', '.join(flags)})" if self.n_flagged else ""
        failed = (f"; {self.n_not_localized} windows not localized "
                  f"(e.g. {self.not_localized_reason})" if self.n_not_localized else "")
        return (f"{self.n_windows} windows, {self.n_valid_tdoas} valid TDOAs, "
                f"{self.n_sources} sources{flagged}{failed}")


#: A source fixed by this many TDOAs or fewer has no redundancy (three fix a point in 3-D).
FEW_TDOAS = 3


def source_flags(src: dict) -> tuple[bool, bool, bool]:
    """``(unobservable, mirror-ambiguous, few TDOAs)`` of a written source entry."""
    return (not src.get("observable", True), bool(src.get("mirror_ambiguous", False)),
            int(src["tdoas_used"]) <= FEW_TDOAS)


class DocumentText:
    """The ``fusion localize`` JSON of the chunks' parts, in pieces of text, one window at a time.

    Iterating yields the document piece by piece (the caller writes them to its file); the
    ``windows`` are byte for byte what :func:`fusion.io.write_json` writes for
    :func:`result_document` of all the windows (indent 1), without holding them all; the
    ``tracks`` follow from the windows' sources (:func:`track_document_sources`). Once iterated,
    :attr:`summary` counts what was yielded.

    Parameters
    ----------
    parts : iterable of str
        Parts (:func:`localize_chunk`) in chunk order.
    transform : callable, optional
        Applied to each window entry before it is yielded (e.g. the fixes re-solved at the
        recording's sound speed, :meth:`fusion.pipelines.sound_speed.SpeedCalibration.apply`).
    """

    def __init__(self, parts: Iterable[str], transform: Callable[[dict], dict] | None = None):
        self._parts = parts
        self._transform = transform
        self._summary: DocumentSummary | None = None

    @property
    def summary(self) -> DocumentSummary:
        """Counts of the document (available once it has been iterated to its end)."""
        if self._summary is None:
            raise RuntimeError("DocumentText.summary is known once the document has been iterated")
        return self._summary

    def __iter__(self) -> Iterator[str]:
        n = n_valid = n_src = 0
        flag_counts = np.zeros(4, dtype=int)  # unobservable, mirror, few TDOAs, any
        n_failed, reason = 0, ""
        sources_of: list[tuple[float, list[dict]]] = []  # per window: centre, sources (small)
        yield '{\n "windows": ['
        for text in self._parts:
            for w in json.loads(text):
                w = w if self._transform is None else self._transform(w)
                body = json.dumps(w, indent=1, allow_nan=False).replace("\n", "\n  ")
                yield ("," if n else "") + "\n  " + body
                n += 1
                n_valid += sum(1 for d in w["tdoas"] if d["valid"])
                n_src += len(w["sources"])
                if w.get("not_localized"):
                    n_failed += 1
                    reason = reason or w["not_localized"]
                for src in w["sources"]:
                    flags = source_flags(src)
                    flag_counts += np.array([*flags, any(flags)], dtype=int)
                sources_of.append((0.5 * (w["t_start"] + w["t_end"]), w["sources"]))
        tracks = [t.to_dict() for t in track_document_sources(sources_of)]
        body = json.dumps(tracks, indent=1, allow_nan=False).replace("\n", "\n ")
        yield ("\n ]" if n else "]") + ',\n "tracks": ' + body + "\n}\n"
        self._summary = DocumentSummary(n, n_valid, n_src, *(int(v) for v in flag_counts),
                                        n_failed, reason)


def track_document_sources(windows: Sequence[tuple[float, Sequence[dict]]]) -> tuple:
    """Tracks of the sources of written windows (``fusion localize`` JSON entries).

    Sources are linked by position (:class:`fusion.localization.tracks.SourceTracker`'s gate with each
    fix's covariance) -- the TDOA links do not survive the file -- and smoothed; fixes flagged
    unobservable or mirror-ambiguous are not tracked.
    """
    from fusion.localization.localize import SourceFix
    from fusion.localization.tracks import SourceTracker, WindowSources
    from fusion.pipelines.localization import UNBOUNDED_M2

    items = []
    for t_mid, sources in windows:
        fixes = []
        for src in sources:
            cov = np.asarray(src["cov"], dtype=float)
            ok = (src.get("observable", True) and not src.get("mirror_ambiguous", False)
                  and np.all(cov < UNBOUNDED_M2))
            if not ok:
                cov = np.full((3, 3), np.nan)
            fixes.append(SourceFix(
                position=np.array([src["x"], src["y"], src["z"]], dtype=float), covariance=cov,
                information=np.zeros((3, 3)), weights=np.zeros(0),
                tdoas_used=int(src["tdoas_used"]), residual_rms_s=0.0, condition_number=1.0,
                observable=bool(ok), mirror_ambiguous=False, mirror_position=np.full(3, np.nan)))
        items.append(WindowSources(float(t_mid), tuple(fixes)))
    return SourceTracker().track(items)
