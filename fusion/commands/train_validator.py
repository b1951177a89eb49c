"""``fusion train-validator --recording DIR ... --out MODEL.npz``: retrain the TDOA validator.

The validator (step 50, eq. 7-11 of *Localization of Short Duration Periodic Signals*) is a
Gaussian-mixture likelihood ratio over SCM2 features. This command runs the click front end
without validation on labelled recordings, labels each candidate TDOA valid when it lies within
``--tolerance-s`` of a labelled TDOA of its pair at the window centre (else invalid), and fits the
two mixtures; the model is written as plain arrays (npz, never pickle) for
``fusion localize --validator``. ``--replica-out`` also re-estimates the click replica from the
recordings' detected clicks (step 32: align at the correlator peak, average, repeat).

A recording is a folder with ``audio.flac`` (or ``audio.wav``), ``array.json`` and
``tdoa_labels.csv`` (``time,i,j,tau[,source]``: per labelled click, its arrival time at sensor i
and TDOA ``t_i - t_j``, s) -- the layout ``fusion simulate clicks`` writes -- or the files named
one by one with ``--audio``, ``--array`` and ``--labels``.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion._progress import track_progress
from fusion.cli import emit, number, summary
from fusion.commands.localize import MIN_HOP_S

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``train-validator`` subcommand."""
    p = sub.add_parser(
        "train-validator",
        help="retrain the TDOA validator on labelled audio",
        description="Fit the TDOA validator's Gaussian mixtures on labelled recordings.",
    )
    p.add_argument("--recording", type=Path, action="append", default=[],
                   help="folder with audio.flac|wav, array.json, tdoa_labels.csv (repeatable)")
    p.add_argument("--audio", type=Path, default=None, help="audio of one recording")
    p.add_argument("--array", type=Path, default=None, help="array JSON of that recording")
    p.add_argument("--labels", type=Path, default=None, help="labels CSV time,i,j,tau[,source]")
    p.add_argument("--simulated", type=number(int, ge=1), default=0, metavar="N",
                   help="also train on N varied simulated scenarios (seeds 0..N-1 of "
                        "fusion.pipelines.clicks.training.varied_scenario; the shipped model is "
                        "--simulated 40)")
    p.add_argument("--out", type=Path, required=True, help="validator model .npz")
    p.add_argument("--replica-out", type=Path, default=None,
                   help="also write a replica re-estimated from the recordings' clicks (.npz)")
    p.add_argument("--tolerance-s", dest="tolerance", type=number(float, gt=0), default=3e-3,
                   help="largest |tau - label| of a valid candidate's smoothed-click-map "
                        "delay, s (default 0.003, about the SCM pulse half-width)")
    p.add_argument("--components", type=number(int, ge=1), default=None,
                   help="mixture components per class (default: chosen by BIC, 1-4)")
    p.add_argument("--target-far", type=number(float, gt=0, le=0.5), default=0.02,
                   help="false-accept rate of invalid candidates that sets the threshold "
                        "(default 0.02)")
    p.add_argument("--seed", type=number(int, ge=0), default=0, help="fitting seed (default 0)")
    p.add_argument("--window-s", dest="window", type=number(float, gt=0), default=12.0,
                   help="processing window, s (default 12)")
    p.add_argument("--hop-s", dest="hop", type=number(float, ge=MIN_HOP_S), default=2.0,
                   help=f"update period, s, at least {MIN_HOP_S:g} (default 2)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("recording", "audio", "array", "labels"),
                   out_stdout=False, more_outputs=("replica_out",),
                   input_files={"recording": RECORDING_FILES})


#: The files of a ``--recording`` folder (outputs may be none of them).
RECORDING_FILES = ("audio.flac", "audio.wav", "array.json", "tdoa_labels.csv")


def _recordings(args: argparse.Namespace) -> list[tuple[Path, Path, Path]]:
    recs = []
    for d in args.recording:
        if not d.is_dir():
            raise ValueError(f"--recording {d}: not a folder")
        audio = next((d / n for n in ("audio.flac", "audio.wav") if (d / n).is_file()), None)
        if audio is None:
            raise ValueError(f"--recording {d}: no audio.flac or audio.wav in it")
        recs.append((audio, d / "array.json", d / "tdoa_labels.csv"))
    given = [args.audio, args.array, args.labels]
    if any(v is not None for v in given):
        if not all(v is not None for v in given):
            raise ValueError("--audio, --array and --labels go together")
        recs.append(tuple(given))
    if not recs and not args.simulated:
        raise ValueError("no recording given (--recording DIR, --audio/--array/--labels, or "
                         "--simulated N)")
    if args.replica_out is not None and not recs:
        raise ValueError("--replica-out: the replica is re-estimated from recorded clicks; give "
                         "a recording (--recording DIR or --audio/--array/--labels)")
    return recs


def _checked(recordings: list[tuple[Path, Path, Path]]) -> list:
    """(audio path, array, labels) of each recording, its array and labels read and checked."""
    from fusion.io import read_array, read_table
    from fusion.pipelines.clicks.training import TdoaLabels

    checked = []
    for audio_p, array_p, labels_p in recordings:
        array = read_array(array_p)
        table = read_table(labels_p, required=("time", "i", "j", "tau"), optional=("source",),
                           integer=("i", "j", "source"))
        labels = TdoaLabels.from_columns(table.columns)
        if labels.i.max(initial=0) >= array.n_sensors or labels.j.max(initial=0) >= array.n_sensors:
            raise ValueError(f"{labels_p}: sensor index beyond the {array.n_sensors} sensors of "
                             f"{array_p}")
        checked.append((audio_p, array, labels))
    return checked


def run(args: argparse.Namespace) -> int:
    """Train the validator (and the replica) on the recordings; write the model(s)."""
    from fusion._output import atomic_outputs
    from fusion.clicks.replica import estimate_replica, load_replica, write_replica
    from fusion.clicks.scm import ClickMapCorrelator, ScmConfig
    from fusion.io import read_audio
    from fusion.pipelines.clicks import ClickFrontEnd
    from fusion.pipelines.clicks.training import (
        CandidateSet,
        label_windows,
        simulated_training_set,
        train_from_candidates,
    )

    front = ClickFrontEnd(validator=False, refiner=False, hop_s=args.hop,
                          correlator=ClickMapCorrelator(config=ScmConfig(window_s=args.window)))
    zs, ys, ss, replica_parts = [], [], [], []
    counts = []  # lines printed once the model is written: a failing run prints its error only
    recordings = _checked(_recordings(args))  # every check before any work
    for k, (audio_p, array, labels) in enumerate(track_progress(
            recordings, quiet=args.quiet, desc="recordings", unit="rec", total=len(recordings))):
        audio, fs = read_audio(audio_p, n_channels=array.n_sensors)
        windows = front.run_array(audio, fs, array)
        for w, y in zip(windows, label_windows(windows, labels, tol_s=args.tolerance),
                        strict=True):
            if w.tdoas:
                zs.append(np.stack([d.features for d in w.tdoas]))
                ys.append(y)
                ss.append(np.full(y.size, k))
        if args.replica_out is not None:
            replica_parts.append((audio, fs, windows))
        counts.append(f"{audio_p}: {sum(len(w.tdoas) for w in windows)} candidate TDOAs, "
                      f"{int(sum(y.sum() for y in ys))} valid so far")
    if args.simulated:
        seeds = track_progress(range(args.simulated), quiet=args.quiet, desc="simulated",
                               unit="rec", total=args.simulated)
        sim = simulated_training_set(seeds, front_end=front,
                                     tol_s=args.tolerance)
        zs.append(sim.z)
        ys.append(sim.valid)
        ss.append(-1 - sim.seed)
        counts.append(f"{args.simulated} simulated scenarios: {sim.valid.size} candidate "
                      f"TDOAs, {int(sim.valid.sum())} valid")
    if not zs:
        raise ValueError("the recordings gave no candidate TDOAs (no clicks detected?)")
    data = CandidateSet(np.concatenate(zs), np.concatenate(ys), np.concatenate(ss))
    model = train_from_candidates(data, n_components=args.components, seed=args.seed,
                                  target_far=args.target_far)
    replica = None
    if args.replica_out is not None:
        audio, fs, windows = replica_parts[0]  # the first recording's clicks, every channel
        times = [np.unique(np.concatenate([w.clicks[ch].times_s for w in windows]))
                 for ch in range(audio.shape[1])]
        replica = estimate_replica(audio, fs, times, initial=load_replica()).replica
        n_clicks = sum(t.size for t in times)
    # both outputs written together, each under exactly the name given
    outs = (args.out,) if replica is None else (args.out, args.replica_out)
    with atomic_outputs(*outs, suffixes=(".npz",) * len(outs)) as tmps:
        model.save(tmps[0])
        if replica is not None:
            write_replica(tmps[1], replica)
    for line in counts:
        emit(line, err=True)
    also = ("" if replica is None else
            f"; replica re-estimated from {n_clicks} clicks -> {args.replica_out}")
    summary("train-validator", f"{int(data.valid.sum())} valid / {int((~data.valid).sum())} "
            f"invalid candidates, threshold {model.threshold:.3g} -> {args.out}{also}", err=True)
    return 0
