"""``fusion tqi --amplitudes A.csv --out Q.csv``: track quality indicator of tracker outputs.

Reads ``track_id,time,amplitude,residual`` (amplitude: cell power, linear, normalised so that
noise alone has mean 1; residual: bearing error, deg), runs the track quality indicator with
hysteresis on every track (all tracks at once, vectorised), and writes the input columns plus
``tqi`` (``lost``, ``uncertain``, ``low_snr``, ``strong``) in the input's row order -- after
:func:`fusion.io.read_amplitudes` has put rows that were out of time order within a track in time
order (one warning says so); two updates of one track at the same time are an error.

The file is read and written in chunks of rows (:func:`fusion.io.iter_amplitudes`,
:func:`fusion.io.write_table_chunks`): the TQI is recursive per track, so each chunk's updates
follow from the memory the chunk before left, and memory stays one chunk plus one memory entry
per track, whatever the file's length. The output is byte-identical to that of the whole table at
once. A file whose rows are out of time order within a track cannot be streamed; it is then read
whole (and sorted, with the warning).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion._progress import track_progress
from fusion.cli import DB_RANGE, MAX_SCANS_OPTION, number, summary
from fusion.io import (
    RowOrderError,
    TableChunk,
    iter_amplitudes,
    read_amplitudes,
    write_table,
    write_table_chunks,
)
from fusion.passive.quality import LABELS, TQIMemory, TrackQualityIndicator
from fusion.pipelines.track_quality import (
    DIAGNOSTICS,
    INPUT_COLUMNS,
    quality_columns,
    update_grid,
)

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``tqi`` subcommand."""
    p = sub.add_parser(
        "tqi",
        help="track quality (lost/uncertain/low_snr/strong) of tracker outputs",
        description="Track quality indicator with hysteresis of narrowband tracker outputs "
        "(amplitude and bearing residual per update).",
    )
    p.add_argument("--amplitudes", type=Path, required=True,
                   help="CSV track_id,time,amplitude,residual")
    p.add_argument("--out", type=Path, required=True, help="output CSV (input columns + tqi)")
    g = p.add_argument_group("design SNRs (per cell)")
    g.add_argument("--snr0-db", type=number(float, ge=DB_RANGE[0], le=DB_RANGE[1]), default=3.0,
                   help="tracker threshold SNR_0, dB (default 3)")
    g.add_argument("--snr1-db", type=number(float, ge=DB_RANGE[0], le=DB_RANGE[1]), default=10.0,
                   help="strong-track SNR_1, dB (default 10)")
    g.add_argument("--n-looks", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=1,
                   help="periodogram looks averaged per cell of the spectra, count (default 1)")
    t = p.add_argument_group("thresholds (method defaults)")
    t.add_argument("--tl", type=number(float), default=-3.5,
                   help="lost threshold TL, dimensionless (default -3.5)")
    t.add_argument("--tu", type=number(float), default=1.75,
                   help="uncertain threshold TU, dimensionless (default 1.75)")
    t.add_argument("--ts", type=number(float), default=7.0,
                   help="strong threshold TS, dimensionless (default 7.0)")
    t.add_argument("--lh", type=number(float, ge=0), default=1.5,
                   help="low-SNR hysteresis LH, dimensionless (default 1.5)")
    t.add_argument("--sh", type=number(float, ge=0), default=2.0,
                   help="strong-SNR hysteresis SH, dimensionless (default 2.0)")
    t.add_argument("--sllr0-max", type=number(float), default=None, metavar="TM0",
                   help="ceiling TM_0 of SLLR_0: how much evidence a loss must undo before "
                        "'lost' (default TU + LH + 0.25; above TU + LH so a track can leave "
                        "'uncertain'); lower: earlier 'lost', more state changes")
    t.add_argument("--no-hysteresis", action="store_true",
                   help="single thresholds (LH = SH = 0 in the decision flow)")
    r = p.add_argument_group("residual test")
    r.add_argument("--omega-per-deg", dest="omega", type=number(float, gt=0), default=0.25,
                   help="error-detector angular centre frequency Omega, 1/deg (default 0.25)")
    r.add_argument("--t-err", type=number(float, ge=0), default=3.0,
                   help="residual threshold constant, dimensionless (default 3.0)")
    r.add_argument("--residual-smoothing", type=number(float, gt=0, le=1), default=0.1,
                   help="gain of the recursive residual smoother, (0, 1] (default 0.1)")
    p.add_argument("--diagnostics", action="store_true",
                   help="also write sllr0, sllr1, smoothed_residual, err_max columns")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("amplitudes",))


def run(args: argparse.Namespace) -> int:
    """Compute the TQI of every track and write the output CSV."""
    if not args.snr1_db > args.snr0_db:
        raise ValueError(f"--snr1-db ({args.snr1_db:g}) must exceed --snr0-db ({args.snr0_db:g})")
    if not args.tl < args.tu:
        raise ValueError(f"--tl ({args.tl:g}) must be below --tu ({args.tu:g})")
    if args.sllr0_max is not None and not args.sllr0_max > args.tl - args.lh:
        raise ValueError(f"--sllr0-max ({args.sllr0_max:g}) must exceed the SLLR_0 floor "
                         f"TL - LH ({args.tl - args.lh:g})")
    tqi = _indicator(args)
    streamed = _StreamedTQI(tqi, diagnostics=args.diagnostics)
    try:
        chunks = track_progress(iter_amplitudes(args.amplitudes), quiet=args.quiet, desc="tqi",
                                unit="row", weight=lambda c: len(c.table["time"]))
        write_table_chunks(args.out, map(streamed.columns, chunks),
                           header=_header(args.diagnostics))
        n_tracks, n_rows = streamed.n_tracks, streamed.n_rows
    except RowOrderError as e:  # rows out of order or repeated: the whole-file reader decides
        logger.debug("%s; reading the whole file", e)
        n_tracks, n_rows = _whole_file(args, tqi)
    summary("tqi", f"{n_tracks} track(s), {n_rows} update(s) -> {args.out}")
    return 0


_INPUT = INPUT_COLUMNS
_DIAGNOSTICS = DIAGNOSTICS  # output column: TQIMemory field


def _indicator(args: argparse.Namespace) -> TrackQualityIndicator:
    """The TQI configured by the command line."""
    limits = None if args.sllr0_max is None else (args.tl - args.lh, args.sllr0_max)
    return TrackQualityIndicator(
        snr0_db=args.snr0_db, snr1_db=args.snr1_db, n_looks=args.n_looks, tl=args.tl,
        tu=args.tu, ts=args.ts, lh=args.lh, sh=args.sh, hysteresis=not args.no_hysteresis,
        omega=args.omega, t_err=args.t_err, residual_smoothing=args.residual_smoothing,
        sllr0_limits=limits,
    )


def _header(diagnostics: bool) -> list[str]:
    return [*_INPUT, "tqi", *(_DIAGNOSTICS if diagnostics else ())]


class _StreamedTQI:
    """TQI of tracker rows arriving in chunks; each track's memory carried between chunks.

    ``columns(chunk)`` returns the output columns of a chunk. Within a chunk, the k-th row of
    each track is its k-th update (rows of a track in time order, checked by the reader); the
    updates of all tracks present are stepped together, the rest keep their memory. The step is
    elementwise per track, so the result equals the whole-table run.
    """

    def __init__(self, tqi: TrackQualityIndicator, *, diagnostics: bool) -> None:
        self.tqi = tqi
        self.diagnostics = diagnostics
        self.ids = np.zeros(0, np.int64)  # tracks seen, sorted
        self.memory: TQIMemory | None = None  # one entry per track of `ids`
        self.n_rows = 0

    @property
    def n_tracks(self) -> int:
        return int(self.ids.size)

    def _slots(self, ids: np.ndarray) -> np.ndarray:
        """Memory slots of `ids` (sorted, distinct), adding tracks not seen before."""
        new = np.setdiff1d(ids, self.ids)
        if new.size:
            fresh = self.tqi.initial_memory(new.size)
            old = self.memory if self.memory is not None else fresh
            merged = np.concatenate([self.ids, new])
            order = np.argsort(merged, kind="stable")
            self.memory = TQIMemory(**{
                f: np.concatenate([getattr(old, f)[:self.ids.size], getattr(fresh, f)])[order]
                for f in TQIMemory.__dataclass_fields__})
            self.ids = merged[order]
        return np.searchsorted(self.ids, ids)

    def columns(self, chunk: TableChunk) -> dict[str, np.ndarray]:
        """Output columns (input columns, ``tqi``, diagnostics) of one chunk of rows."""
        table = chunk.table
        tracks, row_k, col, amp, res, valid = update_grid(table)
        slots = self._slots(tracks)
        shape = amp.shape
        fields = list(TQIMemory.__dataclass_fields__)
        mem = TQIMemory(**{f: getattr(self.memory, f)[slots] for f in fields})
        state = np.empty(shape, dtype=np.int8)
        diag = {f: np.empty(shape) for f in _DIAGNOSTICS.values()} if self.diagnostics else {}
        for k in range(shape[0]):
            mem = self.tqi.step(mem, amp[k], res[k], active=valid[k])
            state[k] = mem.state
            for f, arr in diag.items():
                arr[k] = getattr(mem, f)
        for f in fields:
            getattr(self.memory, f)[slots] = getattr(mem, f)
        self.n_rows += len(table)
        out = {name: table[name] for name in _INPUT}
        out["tqi"] = LABELS[state[row_k, col]]
        for name, f in _DIAGNOSTICS.items():
            if self.diagnostics:
                out[name] = diag[f][row_k, col]
        return out


def _whole_file(args: argparse.Namespace, tqi: TrackQualityIndicator) -> tuple[int, int]:
    """The TQI of the whole table at once (rows sorted by the reader if they were out of order)."""
    table = read_amplitudes(args.amplitudes)
    write_table(args.out, quality_columns(table, tqi, diagnostics=args.diagnostics))
    return int(np.unique(table["track_id"]).size), len(table)
