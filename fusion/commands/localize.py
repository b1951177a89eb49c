"""``fusion localize --audio A --array J --out R.json``: whale clicks to TDOAs and sources.

Streams the audio in blocks (never whole), detects clicks once per sample, and per processing
window (12 s every 2 s by default, the method's values) measures candidate TDOAs from smoothed
click maps, validates them (GMM likelihood ratio), refines them to sub-sample precision,
associates them across time and sensor pairs and localizes the sources competing for them
(``docs/formats.md`` section 2). The audio is one multichannel file (channel i = sensor i) or one
mono file per sensor in array order; files of different lengths are trimmed to the shortest (one
warning), a sample-rate mismatch is an error. A progress bar shows on a terminal (``--quiet``
turns it off).

Long recordings (:mod:`fusion.pipelines.clicks.chunks`, :mod:`fusion.scale`): the windows are
processed in chunks of ``--chunk-s`` seconds of consecutive windows (default 60; with
``--workers N`` shorter when the recordings would give fewer than N chunks); each chunk's task
reads its own audio (its windows, one neighbour window on each side and the detector's guards)
from the file(s) with soundfile and localizes its windows, and the chunks are stitched in order.
Memory does not grow with the length of the recording. By default the chunks run one after the
other in this process (no Dask); ``--workers N`` runs them on N worker processes forked from
this one (:class:`fusion.scale.LocalPool`: they inherit its imports and pipeline, no Dask
cluster to start), ``--scheduler ADDRESS`` on an existing Dask scheduler (its workers must read
the same paths). The output is byte for byte the same in every case, and the same as one pass over the
whole recording.

Resume: each finished chunk is written atomically to ``R.json.parts/<key>/chunk-NNNNNN.json``
beside the output, where ``<key>`` is a fingerprint of the inputs (absolute paths, sizes and
modification times of the audio files; the array, validator and replica contents) and of every
option that changes the result (not ``--workers``, ``--scheduler`` or ``--quiet``). Run the same
command again after an interruption and only the missing chunks are computed; the output is
byte-identical to an uninterrupted run. Parts under another key (a changed command) are removed
and never reused. The folder is removed once the output is written. With ``--out -`` the parts
go to a temporary folder (no resume).

A folder of recordings: ``--audio DIR --out OUTDIR`` localizes every multichannel ``.wav`` /
``.flac`` file of DIR (not its sub-folders; all on the one array) into ``OUTDIR/<name>.json``;
the chunks of all the files form one run (on Dask, the files are processed side by side), with
its parts in ``OUTDIR/localize.parts/`` (keyed by every file of the folder).

Sources (:class:`fusion.pipelines.localization.LocalizerSettings`): each window is solved
along direct paths; when every sensor is below the sea surface (z = 0, z up as in the file
formats) and the direct sources leave more than a fifth of the window's valid TDOAs unexplained,
it is solved again reading every TDOA along direct and surface-reflected paths, and that
solution is kept if it explains more (``--surface-paths`` / ``--direct-only`` decide for every
window instead); ``--sea-floor-z-m`` bounds the search
below, ``--candidates`` and ``--min-source-tdoas`` set the candidates per window and the weight
a source needs (by default those of the path reading).

With ``--events E.csv`` (``t_start,t_end[,f_low,f_high]``, events found by any other detector)
each event is localized instead from band-passed waveform cross-correlation TDOAs of every pair,
screened by triangle closure, solved on the factor graph with its covariance and 95 % interval,
and checked against the eq. 17 intensity surface (:mod:`fusion.localization.events`); nothing assumes
kilometre scales (the search box follows the array's aperture).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
from pathlib import Path

from fusion.cli import emit, number, summary
from fusion.click_defaults import (
    DETECT_FALSE_ALARMS_PER_S,
    SENSOR_POSITION_SIGMA_M,
    TRAIN_FALSE_ALARMS,
)

#: Default of --max-tdoa-rate (fusion.clicks.scm.MAX_TDOA_RATE, not imported here: --help stays
#: light).
MAX_TDOA_RATE = 1.6e-3
#: Most candidates per window (--candidates): each is a graph re-solved in every iteration of the
#: competition and compared with every other one (K^2 pairs an iteration); 16 times the default.
MAX_CANDIDATES = 256
#: Shortest update period (--hop-s, also of train-validator), s: 3 samples of the 3 kHz click map;
#: windows closer than that repeat one map (and a hop of 1 us made 3 million windows of a 3-s
#: recording, hours of work).
MIN_HOP_S = 1e-3
#: Most local worker processes per core (--workers): each holds its own audio blocks and
#: models; past a few per core they add memory, not speed.
MAX_WORKERS_PER_CORE = 4


def max_workers() -> int:
    """The largest ``--workers`` on this machine: :data:`MAX_WORKERS_PER_CORE` per core."""
    return MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``localize`` subcommand."""
    p = sub.add_parser(
        "localize",
        help="localize clicking sources (whales) from multichannel audio",
        description="Detect clicks, measure, validate and associate TDOAs, localize sources.",
        epilog="Long recordings are read in blocks and processed in chunks of --chunk-s seconds: "
               "serially in this process by default, on forked worker processes with --workers, on "
               "Dask with --scheduler (the "
               "output is the same byte for byte). Finished chunks are kept in OUT.parts/ "
               "beside the output; after an interruption, run the same command again to resume. "
               "The folder is removed when the output is written. Each window is solved "
               "along direct paths, and along surface-reflected paths too (sensors below the "
               "sea surface z = 0, z up) where the direct sources leave its TDOAs "
               "unexplained.",
    )
    p.add_argument("--audio", type=Path, nargs="+", required=True, action=_AudioPaths,
                   help="one multichannel WAV/FLAC, or one mono file per sensor in array order, "
                        "or one folder of multichannel recordings (then --out is a folder)")
    p.add_argument("--array", type=Path, required=True, help="array JSON (sensors, sound speed)")
    p.add_argument("--out", type=Path, required=True,
                   help="result JSON (a folder of them for a folder of recordings)")
    p.add_argument("--window-s", dest="window", type=number(float, gt=0), default=12.0,
                   help="processing window, s (default 12)")
    p.add_argument("--hop-s", dest="hop", type=number(float, ge=MIN_HOP_S), default=2.0,
                   help=f"update period, s, at least {MIN_HOP_S:g} (default 2)")
    p.add_argument("--band-hz", dest="band", type=number(float, gt=0), nargs=2, metavar=("LOW", "HIGH"),
                   default=None,
                   help="click detection band, Hz (default: the -10 dB band of the replica "
                        "estimated from the recording, at least 26 kHz wide, below 0.95 of the "
                        "Nyquist frequency; 14000 40000, the method's, without an estimate)")
    p.add_argument("--min-centre-freq-hz", dest="min_centre_freq", type=number(float, ge=0), default=20000.0,
                   help="smallest click centre frequency (eq. 2), Hz (default 20000)")
    detect = p.add_mutually_exclusive_group()
    detect.add_argument("--detect-threshold", type=number(float, gt=0), default=None,
                        help="fixed click detection threshold on the normalised band power "
                             "(default: set from --detect-false-alarms-per-s; 6 is the "
                             "detector's fixed one)")
    detect.add_argument("--detect-false-alarms-per-s", dest="detect_false_alarms",
                        type=number(float, gt=0, le=50), default=DETECT_FALSE_ALARMS_PER_S,
                        metavar="RATE",
                        help="click detection threshold at this many detections per channel-"
                             "second in white Gaussian noise, measured on the detector's own "
                             f"statistic (default {DETECT_FALSE_ALARMS_PER_S:g})")
    p.add_argument("--validator", type=Path, default=None,
                   help="validator model .npz (default: the one shipped; see train-validator)")
    p.add_argument("--replica", default=None, metavar="NPZ|generic",
                   help="click replica: a .npz file, or 'generic' for the one shipped (default: "
                        "estimated from the strongest clicks of the first 60 s "
                        "of the recording, starting from the shipped one)")
    p.add_argument("--llr-threshold", type=float, default=None,
                   help="validation threshold on the log-likelihood ratio (default: 0.5, just "
                        "above even odds, with the shipped validator; a --validator file's own "
                        "threshold)")
    p.add_argument("--max-tdoa-rate", type=number(float, ge=0, le=0.05), default=MAX_TDOA_RATE,
                   metavar="S_PER_S",
                   help="largest delay drift d tau/dt the click-map correlation compensates, s/s "
                        f"(default {MAX_TDOA_RATE:g}: whales up to ~2.4 m/s; 0: none, the method "
                        "text's correlation)")
    p.add_argument("--keep-aliases", action="store_true",
                   help="keep TDOAs that re-pair the clicks of a stronger TDOA of their pair one "
                        "click apart (default: they fail validation: one delay per click train)")
    p.add_argument("--no-closure-support", action="store_true",
                   help="admit no TDOA that failed validation (default: where the validated "
                        "TDOAs of a window span fewer than four sensors, partial click trains "
                        "of another sensor that close with them are admitted)")
    p.add_argument("--no-train-integration", action="store_true",
                   help="no TDOAs from click trains summed on weakly heard sensors (default: "
                        "where the validated TDOAs of a window span fewer than four sensors, each "
                        "other sensor's detection statistic is summed along a well-heard sensor's "
                        "click train; docs/localization.md section 19)")
    p.add_argument("--train-false-alarms-per-pair", type=number(float, gt=0, le=0.5),
                   default=TRAIN_FALSE_ALARMS, metavar="P",
                   help="false-alarm probability of one (window, sensor pair) train search "
                        f"(default {TRAIN_FALSE_ALARMS:g})")
    p.add_argument("--no-train-refine", action="store_true",
                   help="train-integrated delays as read off the detection statistic (default: "
                        "refined on the waveforms; docs/localization.md section 23)")
    p.add_argument("--strong-echoes-only", action="store_true",
                   help="count a sensor's bottom echo only at the full evidence threshold "
                        "(default: once one sensor shows one, weaker evidence on the others "
                        "counts too and widens the echo window)")
    p.add_argument("--no-refine", action="store_true",
                   help="keep TDOAs on the smoothed-click-map grid (no waveform refinement)")
    p.add_argument("--method", choices=("competition", "eq18", "eq17", "lsq", "none"),
                   default="competition",
                   help="localization: competing candidates (default), the eq. 18 or eq. 17 "
                        "surface peak, one least-squares source, or none (TDOAs only)")
    paths = p.add_mutually_exclusive_group()
    paths.add_argument("--surface-paths", dest="surface_paths", action="store_const", const=True,
                       default=None,
                       help="read every TDOA of every window along direct and "
                            "surface-reflected paths (the sea surface at z = 0, z up); default: "
                            "decided per window from the data")
    paths.add_argument("--direct-only", dest="surface_paths", action="store_const", const=False,
                       help="read TDOAs along direct paths only (always so, with one logged "
                            "line, when a sensor is not below z = 0)")
    p.add_argument("--sea-floor-z-m", dest="sea_floor_z", type=number(float), default=None, metavar="Z",
                   help="height of the sea floor, m (z up, e.g. -1700; at or below every sensor): "
                        "sources are searched between it and the surface (default: 30 m under "
                        "the deepest sensor, which hears bottom echoes or is taken as "
                        "bottom-mounted; sensors not all below z = 0: unknown)")
    p.add_argument("--sound-speed", choices=("estimate", "array"), default="estimate",
                   help="estimate (default): one sound speed for the recording, estimated on a "
                        "factor graph from all its fixes, and every fix re-solved at it (the "
                        "array file's speed only starts it); array: the array file's speed")
    p.add_argument("--no-far-delays", dest="far_delays", action="store_false",
                   help="estimate the sound speed from the delays the fixes own only (ablation): "
                        "by default, when fewer than 3 fixes span 5 sensors, a sensor's candidate "
                        "delays below the validator's bar are recruited where the windows agree "
                        "on the speed they imply")
    p.add_argument("--no-speed-gradient", dest="speed_gradient", action="store_false",
                   help="estimate one sound speed (ablation): by default a speed linear in "
                        "depth (a speed and its depth gradient, where the fixes tell it), "
                        "every fix re-solved along straight rays through it")
    p.add_argument("--sensor-position-sigma-m", dest="sensor_position_sigma",
                   type=number(float, ge=0, le=100), default=SENSOR_POSITION_SIGMA_M, metavar="M",
                   help="standard deviation of the array file's sensor positions per axis, m "
                        f"(default {SENSOR_POSITION_SIGMA_M:g}, an assumed survey accuracy): "
                        "each sensor's offset is estimated with the sound speed from all fixes "
                        "and used where it fits them significantly better (F test on the "
                        "offset parameters the fixes determine) and explains fixes left out "
                        "of its fit, every fix re-solved at the refined positions (printed, and "
                        "written beside the output with their sigmas); 0: positions exact")
    p.add_argument("--candidates", type=number(int, ge=1, le=MAX_CANDIDATES), default=None,
                   metavar="N", help="candidates per window, at most "
                   f"{MAX_CANDIDATES} (default 16 reading surface paths, 8 direct)")
    p.add_argument("--min-source-tdoas", type=number(float, gt=0), default=None, metavar="W",
                   help="smallest total TDOA weight of a source (default 5.5 reading surface "
                        "paths, 3.5 direct)")
    p.add_argument("--min-redundant-tdoas", type=number(int, ge=0), default=0, metavar="N",
                   help="TDOAs a source needs beyond the three unknowns of its position "
                        "(1: three TDOAs fit some position exactly, so a fix on three cannot "
                        "be tested; default 0, off: it starved the sound-speed estimate of "
                        "three-whale recordings)")
    p.add_argument("--echo-ghost-lag-s", type=number(float, ge=0), default=0.0, metavar="S",
                   help="longest bottom-echo lag, s, of the echo-ghost test: a source whose "
                        "TDOAs are another's moved by echo lags on at most two sensors is "
                        "dropped (e.g. 0.03, the front end's longest echo lag; default 0: off)")
    p.add_argument("--drop-echo-only-sources", action="store_true",
                   help="drop a source that hears some sensor only through its surface echo "
                        "(the direct click is louder and earlier than its echo; off by "
                        "default: it also drops true fixes when the array file's sound speed "
                        "is off)")
    p.add_argument("--events", type=Path, default=None,
                   help="CSV t_start,t_end[,f_low,f_high] of events found by another detector: "
                        "localize each event from band-passed waveform cross-correlation "
                        "instead of detecting clicks")
    p.add_argument("--chunk-s", dest="chunk", type=number(float, gt=0), default=None,
                   help="audio per task, s: consecutive windows processed (and recorded for "
                        "resuming) together (default 60; with --workers N, shorter where the "
                        "recordings would give fewer than N chunks)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=number(int, ge=1, le=max_workers()), default=None,
                       help="run the chunks on this many worker processes forked from this "
                            f"one, at most {MAX_WORKERS_PER_CORE} per core ({max_workers()} "
                            "here) (default: serially in this process, no Dask)")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run the chunks on the Dask scheduler at ADDRESS (tcp://host:8786); "
                            "its workers must read the same audio paths")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    from fusion.commands.localize_events import add_event_options

    add_event_options(p)
    p.set_defaults(handler=run, inputs=("audio", "array", "events"),
                   outputs_together=False)  # resumes from its parts: reads back what it wrote


def _decided(args: argparse.Namespace, pipe, source, array):
    """The pipeline with the replica, band, echo suppression and sea floor decided from the
    first minute of the first recording, and the decisions: the library's own step
    (:meth:`fusion.pipelines.localization.ClickLocalization.with_recording_decisions`, which
    ``ClickLocalization()`` takes on every recording), with the options of this command."""
    from fusion.pipelines.from_recording import RECORDING_SPAN_S

    given = args.replica not in (None, "generic")
    n = min(source.frames, int(round(RECORDING_SPAN_S * source.fs)))
    first = source.start_samples(n)  # kept for the first chunk: decoded once
    return pipe.with_recording_decisions(
        first, source.fs, array, estimate_replica=args.replica is None,
        estimate_band=args.band is None,
        replica_source=str(args.replica) if given else "generic",
        span=f"the first {n / source.fs:.3g} s of {Path(source.paths[0]).name}",
        weak_echoes=not args.strong_echoes_only)


class _AudioPaths(argparse.Action):
    """``--audio``: the paths; one folder makes ``--out`` a folder too."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: list[Path], option_string: str | None = None) -> None:
        setattr(namespace, self.dest, values)
        namespace.out_is_dir = len(values) == 1 and Path(values[0]).is_dir()
        if namespace.out_is_dir:  # declared to the output guard (fusion.cli.check_paths)
            from fusion.io.audio import audio_files_of

            namespace.out_files = (*(f"{p.stem}.json" for p in audio_files_of(Path(values[0]))),
                                   "localize.settings.json")


def _recordings(args: argparse.Namespace, n_sensors: int) -> list:
    """(AudioSource, output path) of each recording to localize."""
    from fusion.io import check_audio_files
    from fusion.io.audio import audio_files_of
    from fusion.pipelines.clicks.chunks import AudioSource

    def open_audio(paths: list, n: int) -> AudioSource:  # the checks live in fusion.io
        return AudioSource.of(check_audio_files(paths, n))

    if not getattr(args, "out_is_dir", False):
        return [(open_audio(list(args.audio), n_sensors), args.out)]
    folder = Path(args.audio[0])
    files = audio_files_of(folder)
    if not files:
        raise ValueError(f"--audio {folder}: no .wav or .flac recordings in the folder")
    stems = [p.stem for p in files]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise ValueError(f"--audio {folder}: recordings {twice} would share an output name")
    return [(open_audio([p], n_sensors), Path(args.out) / f"{p.stem}.json") for p in files]


#: Audio per chunk, s, unless --chunk-s says otherwise.
CHUNK_S = 60.0


def _default_chunk_s(recordings: list, pipe, workers: int | None) -> float:
    """:data:`CHUNK_S`, or with `workers` local workers and fewer chunks than workers, the
    hop multiple that gives each worker a chunk of the longest recording (the result is the
    same for any chunking: :mod:`fusion.pipelines.clicks.chunks`)."""
    from fusion.pipelines.clicks.stream import window_starts_count

    front = pipe.front_end
    counts = [window_starts_count(source.duration_s, front.window_s, front.hop_s)
              for source, _ in recordings]
    per = max(1, int(round(CHUNK_S / front.hop_s)))
    if not workers or sum(-(-n // per) for n in counts) >= workers:
        return CHUNK_S
    return front.hop_s * max(1, -(-max(counts) // int(workers)))


def _run_key(args: argparse.Namespace, audio: list) -> str:
    """Fingerprint of the inputs and of every option that changes the result (resume key)."""
    from fusion import __version__
    from fusion.clicks.replica import GENERIC_PATH
    from fusion.clicks.validate import DEFAULT_MODEL_PATH as shipped_validator
    from fusion.scale import file_identity, fingerprint

    return fingerprint({
        "version": __version__,
        "audio": [file_identity(p) for p in audio],
        "array": file_identity(args.array, content=True),
        "validator": file_identity(args.validator or shipped_validator, content=True),
        "replica": (args.replica or "estimated") if args.replica in (None, "generic")
        else file_identity(args.replica, content=True),
        "generic_replica": file_identity(GENERIC_PATH, content=True),
        "options": {k: getattr(args, k) for k in (
            "window", "hop", "band", "min_centre_freq", "detect_threshold", "detect_false_alarms",
            "llr_threshold", "no_refine", "keep_aliases", "no_closure_support",
            "no_train_integration", "train_false_alarms_per_pair", "no_train_refine",
            "strong_echoes_only", "max_tdoa_rate", "method", "chunk",
            "surface_paths", "sea_floor_z",
            "candidates", "min_source_tdoas", "min_redundant_tdoas",
            "echo_ghost_lag_s", "drop_echo_only_sources")},
    })


def run(args: argparse.Namespace) -> int:
    """Run the click localization (or, with ``--events``, the event localization)."""
    if args.events is not None:
        from fusion.commands.localize_events import run_events

        if getattr(args, "out_is_dir", False):
            raise ValueError("--events localizes one recording: give its file(s), not a folder")

        return run_events(args)
    from fusion._output import STDOUT, atomic_output, output_lock, private_folder
    from fusion._progress import WindowProgress
    from fusion.clicks.band import DEFAULT_BAND_HZ
    from fusion.clicks.detect import ClickDetector
    from fusion.clicks.replica import load_replica
    from fusion.clicks.scm import ClickMapCorrelator, ScmConfig, drift_grid
    from fusion.clicks.validate import TdoaValidator
    from fusion.io import read_array, write_settings
    from fusion.pipelines.clicks import LLR_THRESHOLD, ClickFrontEnd, default_validator
    from fusion.pipelines.clicks.chunks import (
        ChunkTask,
        DocumentText,
        localize_chunk,
        plan_chunks,
    )
    from fusion.pipelines.localization import ClickLocalization, settings_from_args
    from fusion.scale import PartStore, progress, run_tasks, task_runner

    if args.hop > args.window:
        raise ValueError(f"--hop-s {args.hop} is longer than --window-s {args.window}")
    lo, hi = DEFAULT_BAND_HZ if args.band is None else args.band
    if not lo < hi:
        raise ValueError(f"--band-hz: low edge {lo} must be below the high edge {hi}")
    array = read_array(args.array)
    recordings = _recordings(args, array.n_sensors)
    for source, _ in recordings:
        if hi >= source.fs / 2:
            raise ValueError(f"{source.paths[0]}: sample rate {source.fs:g} Hz is too low for the "
                             f"click band up to {hi:g} Hz (needs > {2 * hi:g} Hz; see --band-hz)")
    det_opts = {"band_hz": (lo, hi), "min_centre_freq_hz": args.min_centre_freq}
    if args.detect_threshold is not None:
        det_opts["threshold"] = args.detect_threshold
    else:  # the windows' threshold from a noise false-alarm rate (docs/localization.md)
        det_opts["false_alarms_per_s"] = args.detect_false_alarms
    validator = (TdoaValidator.load(args.validator) if args.validator is not None
                 else default_validator(LLR_THRESHOLD))
    if args.llr_threshold is not None:
        validator = dataclasses.replace(validator, threshold=args.llr_threshold)
    # checked (and the direct-path fallback logged) once for the array; the pipeline resolves
    # the localizers, with the surface-path reading decided per window from the data
    localizer = None if args.method == "none" else settings_from_args(args)
    if localizer is not None:
        localizer.localizers(array.positions)
    given = args.replica not in (None, "generic")
    front = ClickFrontEnd(
        detector=ClickDetector(**det_opts, **({"replica": load_replica(Path(args.replica))}
                                              if given else {})),
        correlator=ClickMapCorrelator(config=ScmConfig(window_s=args.window),
                                      rates=drift_grid(args.max_tdoa_rate)),
        validator=validator, refiner=not args.no_refine, hop_s=args.hop,
        alias_screen=not args.keep_aliases, closure_support=not args.no_closure_support,
        train_integration=not args.no_train_integration, train_refine=not args.no_train_refine,
        train_false_alarms=args.train_false_alarms_per_pair)
    pipe, decided = _decided(args, ClickLocalization(front_end=front, localizer=localizer),
                             recordings[0][0], array)
    localizer = pipe.settings
    detector = pipe.front_end.detector  # the decisions read strong clicks at the fixed threshold
    level = detector.threshold_at(recordings[0][0].fs)  # measured here, before any fork
    detection = {"threshold": level, "false_alarms_per_s": detector.false_alarms_per_s}
    detection_note = (f"detection threshold: {level:.3g}" + (
        f", where the detector passes {detector.false_alarms_per_s:g} noise detections a "
        "channel-second (--detect-threshold for a fixed one)"
        if detector.false_alarms_per_s is not None else " (fixed)"))
    if args.chunk is None:
        args.chunk = _default_chunk_s(recordings, pipe, args.workers)
    plans = [plan_chunks(source, pipe, chunk_s=args.chunk) for source, _ in recordings]
    tasks = [t for plan in plans for t in plan]
    if len(recordings) == 1:
        def name(t: ChunkTask) -> str:
            return t.name
    else:
        number_of = {source: i for i, (source, _) in enumerate(recordings)}

        def name(t: ChunkTask) -> str:
            return f"{number_of[t.source]:05d}-{t.name}"
    notes: list[str] = []
    with contextlib.ExitStack() as stack:
        stack.enter_context(output_lock(args.out))  # one run per output (none for stdout)
        if str(args.out) == STDOUT:  # no resume: parts in a private temporary folder
            root = stack.enter_context(private_folder("fusion-localize-")) / "parts"
        elif len(recordings) > 1 or getattr(args, "out_is_dir", False):
            root = Path(args.out) / "localize.parts"
        else:
            root = Path(f"{args.out}.parts")
        audio = [p for source, _ in recordings for p in source.paths]
        store = PartStore(root, key=_run_key(args, audio)[:32])
        bar = progress(sum(plan[-1].stop_window for plan in plans), quiet=args.quiet,
                       desc="localize", unit="window")
        stack.callback(bar.close)
        missing = {name(t) for t in tasks} - store.names()
        client = (stack.enter_context(task_runner(workers=args.workers, scheduler=args.scheduler))
                  if missing else None)  # nothing left to compute: no cluster
        shown = WindowProgress(bar, in_process=client is None)
        shared = (pipe, array) if client is not None else (pipe, array, shown.window)
        run_tasks(localize_chunk, shared, tasks, names=name, store=store, client=client,
                  on_done=shown.chunk_done)
        bar.close()
        speeds, summaries = {}, []
        for (_, out), plan in zip(recordings, plans, strict=True):
            transform = None
            if args.sound_speed == "estimate" and localizer is not None:
                from fusion.pipelines.sound_speed import calibrate_speed

                cal = calibrate_speed((w for t in plan for w in json.loads(store.read(name(t)))),
                                      array.positions, array.sound_speed,
                                      recruit_far=args.far_delays,
                                      gradient=args.speed_gradient,
                                      sensor_sigma_m=args.sensor_position_sigma)
                transform, speeds[str(out)] = cal.apply, cal.record()
                notes.append(cal.note if len(recordings) == 1 else f"{out}: {cal.note}")
            document = DocumentText((store.read(name(t)) for t in plan), transform=transform)
            with atomic_output(out) as tmp, open(tmp, "w", encoding="utf-8") as f:
                f.writelines(document)
            summaries.append(f"{document.summary.line()} -> {out}")
        store.remove()
        side = (Path(args.out) / "localize" if getattr(args, "out_is_dir", False)
                else args.out)
        write_settings(side, {"command": "localize", **decided.record, "detection": detection,
                              "localization": None if localizer is None else localizer.to_dict(),
                              **({"sound_speed": speeds} if speeds else {})},
                       inputs=[*audio, args.array, args.events, args.validator])
    for note in [*decided.notes, detection_note, *notes]:
        emit(note, err=True)
    for line in summaries:  # the command ends with its summary (one line per recording)
        summary("localize", line, err=True)
    return 0
