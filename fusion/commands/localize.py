"""``fusion localize --audio A --array J --out R.json``: whale clicks to TDOAs and sources.

Streams the audio in blocks (never whole), detects clicks once per sample, and per processing
window (12 s every 2 s by default, the method's values) measures candidate TDOAs from smoothed
click maps, validates them (GMM likelihood ratio), refines them to sub-sample precision,
associates them across time and sensor pairs and localizes the sources competing for them
(``docs/formats.md`` section 2). The audio is one multichannel file (channel i = sensor i) or one
mono file per sensor in array order; files of different lengths are trimmed to the shortest (one
warning), a sample-rate mismatch is an error. A progress bar shows on a terminal (``--quiet``
turns it off).

With ``--events E.csv`` (``t_start,t_end[,f_low,f_high]``, events found by any other detector)
each event is localized instead from band-passed waveform cross-correlation TDOAs of every pair,
screened by triangle closure, solved on the factor graph with its covariance and 95 % interval,
and checked against the eq. 17 intensity surface (:mod:`fusion.clicks.events`); nothing assumes
kilometre scales (the search box follows the array's aperture).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from fusion.cli import emit, number


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``localize`` subcommand."""
    p = sub.add_parser(
        "localize",
        help="localize clicking sources (whales) from multichannel audio",
        description="Detect clicks, measure, validate and associate TDOAs, localize sources.",
    )
    p.add_argument("--audio", type=Path, nargs="+", required=True,
                   help="one multichannel WAV/FLAC, or one mono file per sensor in array order")
    p.add_argument("--array", type=Path, required=True, help="array JSON (sensors, sound speed)")
    p.add_argument("--out", type=Path, required=True, help="result JSON")
    p.add_argument("--window", type=number(float, gt=0), default=12.0,
                   help="processing window, s (default 12)")
    p.add_argument("--hop", type=number(float, gt=0), default=2.0,
                   help="update period, s (default 2)")
    p.add_argument("--band", type=number(float, gt=0), nargs=2, metavar=("LOW", "HIGH"),
                   default=(14000.0, 40000.0), help="click detection band, Hz (default 14000 40000)")
    p.add_argument("--min-centre-freq", type=number(float, ge=0), default=20000.0,
                   help="smallest click centre frequency (eq. 2), Hz (default 20000)")
    p.add_argument("--detect-threshold", type=number(float, gt=0), default=None,
                   help="click detection threshold on the normalised band power (default: the "
                        "detector's)")
    p.add_argument("--validator", type=Path, default=None,
                   help="validator model .npz (default: the one shipped; see train-validator)")
    p.add_argument("--replica", type=Path, default=None,
                   help="replica .npz (default: the generic replica shipped)")
    p.add_argument("--llr-threshold", type=float, default=None,
                   help="validation threshold on the log-likelihood ratio (default: the model's)")
    p.add_argument("--no-refine", action="store_true",
                   help="keep TDOAs on the smoothed-click-map grid (no waveform refinement)")
    p.add_argument("--method", choices=("competition", "eq18", "eq17", "lsq", "none"),
                   default="competition",
                   help="localization: competing candidates (default), the eq. 18 or eq. 17 "
                        "surface peak, one least-squares source, or none (TDOAs only)")
    p.add_argument("--events", type=Path, default=None,
                   help="CSV t_start,t_end[,f_low,f_high] of events found by another detector: "
                        "localize each event from band-passed waveform cross-correlation "
                        "instead of detecting clicks")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    from fusion.commands.localize_events import add_event_options

    add_event_options(p)
    p.set_defaults(handler=run, inputs=("audio", "array", "events"))


def _blocks(paths: list[Path], n_channels: int, hop_s: float) -> tuple[Iterator, float, float]:
    """Consecutive audio blocks of `hop_s` from one multichannel file or one mono file each."""
    import soundfile as sf

    infos = []
    for p in paths:
        try:
            infos.append(sf.info(str(p)))
        except (RuntimeError, sf.LibsndfileError) as e:
            raise ValueError(f"{p}: not a readable WAV/FLAC audio file ({e})") from None
    if len(paths) == 1:
        if infos[0].channels != n_channels:
            raise ValueError(f"{paths[0]}: audio has {infos[0].channels} channel(s) but the "
                             f"array has {n_channels} sensors")
    else:
        if len(paths) != n_channels:
            raise ValueError(f"{len(paths)} audio files for {n_channels} sensors (give one "
                             "multichannel file or one mono file per sensor)")
        for p, info in zip(paths, infos, strict=True):
            if info.channels != 1:
                raise ValueError(f"{p}: expected a mono file, got {info.channels} channels")
    rates = {float(i.samplerate) for i in infos}
    if len(rates) != 1:
        listing = ", ".join(f"{p} {i.samplerate} Hz" for p, i in zip(paths, infos, strict=True))
        raise ValueError(f"audio files have different sample rates: {listing}")
    fs = rates.pop()
    frames = min(i.frames for i in infos)
    if frames == 0:
        raise ValueError(f"{paths[0]}: audio file has no samples")
    if len({i.frames for i in infos}) > 1:
        logging.getLogger(__name__).warning(
            "audio files differ in length; trimmed to the shortest (%d samples)", frames)
    block = max(int(round(hop_s * fs)), 1)

    def gen() -> Iterator:
        readers = [sf.blocks(str(p), blocksize=block, dtype="float32", always_2d=True,
                             frames=frames) for p in paths]
        start = 0
        try:
            for parts in zip(*readers, strict=True):
                x = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
                yield start / fs, x
                start += x.shape[0]
        except (RuntimeError, sf.LibsndfileError) as e:
            raise ValueError(f"{paths[0]}: audio could not be decoded ({e})") from None

    return gen(), fs, frames / fs


def run(args: argparse.Namespace) -> int:
    """Run the click localization (or, with ``--events``, the event localization)."""
    if args.events is not None:
        from fusion.commands.localize_events import run_events

        return run_events(args)
    from fusion.clicks.detect import ClickDetector
    from fusion.clicks.localize import MultiSourceLocalizer
    from fusion.clicks.replica import load_replica
    from fusion.clicks.scm import ClickMapCorrelator, ScmConfig
    from fusion.clicks.validate import TdoaValidator
    from fusion.io import read_array, write_json
    from fusion.pipelines.clicks import ClickFrontEnd, default_validator
    from fusion.pipelines.localization import ClickLocalization, result_document

    if args.hop > args.window:
        raise ValueError(f"--hop {args.hop} is longer than --window {args.window}")
    lo, hi = args.band
    if not lo < hi:
        raise ValueError(f"--band: low edge {lo} must be below the high edge {hi}")
    array = read_array(args.array)
    blocks, fs, duration = _blocks(list(args.audio), array.n_sensors, args.hop)
    if hi >= fs / 2:
        raise ValueError(f"{args.audio[0]}: sample rate {fs:g} Hz is too low for the click band "
                         f"up to {hi:g} Hz (needs > {2 * hi:g} Hz; see --band)")
    det_opts = {"band_hz": (lo, hi), "min_centre_freq_hz": args.min_centre_freq}
    if args.detect_threshold is not None:
        det_opts["threshold"] = args.detect_threshold
    if args.replica is not None:
        det_opts["replica"] = load_replica(args.replica)
    validator = (TdoaValidator.load(args.validator) if args.validator is not None
                 else default_validator())
    if args.llr_threshold is not None:
        validator = dataclasses.replace(validator, threshold=args.llr_threshold)
    front = ClickFrontEnd(
        detector=ClickDetector(**det_opts),
        correlator=ClickMapCorrelator(config=ScmConfig(window_s=args.window)),
        validator=validator, refiner=not args.no_refine, hop_s=args.hop)
    localizer = None if args.method == "none" else MultiSourceLocalizer(method=args.method)
    pipe = ClickLocalization(front_end=front, localizer=localizer)
    from fusion.pipelines.clicks import window_starts

    n_windows = int(window_starts(duration, args.window, args.hop).size)
    windows = pipe.iter_windows(blocks, fs=fs, sensors=array, duration_s=duration)
    if not args.quiet and sys.stderr.isatty():
        from tqdm import tqdm

        windows = tqdm(windows, total=n_windows, unit="window", desc="localize")
    done = list(windows)
    write_json(args.out, result_document(done))
    n_valid = sum(len(w.window.valid_tdoas) for w in done)
    n_src = sum(len(w.output.sources) for w in done if w.output is not None)
    emit(f"{len(done)} windows, {n_valid} valid TDOAs, {n_src} sources -> {args.out}", err=True)
    return 0
