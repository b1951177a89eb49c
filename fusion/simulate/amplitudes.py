"""Simulated tracker amplitude and residual sequences: the inputs of ``fusion tqi``.

Each track passes through segments of known condition, and every update draws what a narrowband
bearing tracker (:mod:`fusion.passive.tracker`) reports in that condition:

- **amplitude** ``A(k)``: the power in the tracker's cell on the normalised scale, the mean of
  ``L`` periodogram looks ``|s + n|^2`` (noise ``n`` circular complex Gaussian of unit power, line
  power ``snr``), i.e. ``chi2'(2 L, 2 L snr) / (2 L)``; noise alone is exponential of mean 1 for
  one look. Mean ``1 + snr``, variance ``(1 + 2 snr) / L``
  (:func:`fusion.passive.tracker.cell_power_statistics`).
- **residual** (bearing error, deg): Gaussian of standard deviation
  ``sqrt(floor^2 + spread^2 / (1 + snr))`` plus a bias during a manoeuvre. The two constants
  (0.55 and 3.35 deg by default) approximate the residuals of the tracker on simulated cubes of the
  default geometry (64 beams, 50 m aperture, 300 Hz) at bearings of 60-90 deg: measured 0.8-0.9 deg
  at 15 dB, 1.6-1.7 deg at 6 dB, 2.9-3.0 deg on noise alone (more towards endfire, where a beam
  spans more bearing).

Conditions (truth per update):

``strong``
    SNR ``strong_snr_db`` (well above the strong design SNR).
``near_strong``
    The SNR at which ``LLR_1`` of the track quality indicator has zero mean, ``0.85 SNR_1``
    (linear), so ``SLLR_1`` wanders around the strong threshold.
``near_lost``
    The SNR at which ``LLR_0`` has zero mean, ``SNR_0 / 2`` (linear), so ``SLLR_0`` wanders
    between the lost and uncertain thresholds.
``manoeuvre``
    Strong SNR, with a residual bias of ``manoeuvre_bias_deg`` (the tracker lags the target).
``lost``
    No signal in the cell.

Near-threshold SNRs get a per-segment jitter of ``near_jitter_db`` (uniform, dB).

With ``write_scenario(..., vary=True)`` the assumptions are drawn per scenario from
:data:`VARIED_RANGES` (:func:`varied_settings`): update period, strong SNR and manoeuvre bias
per segment, near-threshold jitter, and segment lengths in seconds.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.io import write_table

__all__ = [
    "CONDITIONS",
    "VARIED_RANGES",
    "AmplitudeScenario",
    "condition_snr_db",
    "draw_amplitudes",
    "draw_residuals",
    "simulate_amplitudes",
    "varied_settings",
    "write_scenario",
]

logger = logging.getLogger(__name__)

#: Condition names, in the order of their codes.
CONDITIONS: tuple[str, ...] = ("strong", "near_strong", "near_lost", "manoeuvre", "lost")

#: Ranges of the assumptions of a varied scenario (:func:`varied_settings`); the update period is
#: drawn log-uniformly per scenario, the others uniformly (per segment where the option is a pair).
VARIED_RANGES: dict[str, tuple[float, float]] = {
    "update_period_s": (1.0, 10.0),  # s, per scenario
    "segment_s": (40.0, 600.0),  # length of one condition, s, per segment
    "segments_per_track": (3, 7),
    "strong_snr_db": (12.0, 25.0),  # per segment, dB
    "near_jitter_db": (0.5, 2.0),  # half-width of the near-threshold jitter, dB, per scenario
    "manoeuvre_bias_deg": (1.5, 5.0),  # per segment, deg
}


def _draw(rng: np.random.Generator, value: float | tuple[float, float]) -> float:
    """`value` itself, or a uniform draw when it is an interval ``(lo, hi)``."""
    if np.ndim(value) == 0:
        return float(value)
    lo, hi = value
    return float(rng.uniform(lo, hi))


def condition_snr_db(
    condition: str, *, snr0_db: float = 3.0, snr1_db: float = 10.0, strong_snr_db: float = 15.0
) -> float:
    """Per-cell SNR of a condition, dB (``-inf`` for ``lost``).

    Parameters
    ----------
    condition : str
        One of :data:`CONDITIONS`.
    snr0_db, snr1_db : float, optional
        Design SNRs of the track quality indicator (tracker threshold, strong), dB.
    strong_snr_db : float, optional
        SNR of a strong track, dB.

    Returns
    -------
    float
        SNR, dB.
    """
    if condition in ("strong", "manoeuvre"):
        return float(strong_snr_db)
    if condition == "near_strong":  # E[LLR_1] = 0 where the mean excess power is 0.85 C_1
        return float(snr1_db + 10.0 * np.log10(0.85))
    if condition == "near_lost":  # E[LLR_0] = 0 where the mean excess power is C_0 / 2
        return float(snr0_db + 10.0 * np.log10(0.5))
    if condition == "lost":
        return float("-inf")
    raise ValueError(f"unknown condition {condition!r} (choose from {', '.join(CONDITIONS)})")


def draw_amplitudes(
    snr_db: ArrayLike, *, rng: np.random.Generator, n_looks: int = 1
) -> NDArray[np.float64]:
    """Tracker cell powers at the given per-cell SNRs (noise mean 1).

    Parameters
    ----------
    snr_db : array_like
        Per-cell SNR of each draw, dB (``-inf``: noise alone).
    rng : numpy.random.Generator
        Random generator.
    n_looks : int, optional
        Periodogram looks averaged in a cell.

    Returns
    -------
    ndarray
        Same shape as `snr_db`: ``chi2'(2 L, 2 L snr) / (2 L)``.
    """
    if int(n_looks) != n_looks or n_looks < 1:
        raise ValueError(f"n_looks must be a positive integer, got {n_looks!r}")
    s = 10.0 ** (np.asarray(snr_db, dtype=float) / 10.0)
    dof = 2.0 * n_looks
    return rng.noncentral_chisquare(dof, dof * s) / dof


def draw_residuals(
    snr_db: ArrayLike,
    *,
    rng: np.random.Generator,
    bias_deg: ArrayLike = 0.0,
    floor_deg: float = 0.55,
    spread_deg: float = 3.35,
) -> NDArray[np.float64]:
    """Tracker bearing residuals at the given SNRs, deg.

    Parameters
    ----------
    snr_db : array_like
        Per-cell SNR of each draw, dB.
    rng : numpy.random.Generator
        Random generator.
    bias_deg : array_like, optional
        Residual bias (broadcast against `snr_db`), deg.
    floor_deg, spread_deg : float, optional
        Standard deviation ``sqrt(floor^2 + spread^2 / (1 + snr))``, deg.

    Returns
    -------
    ndarray
        Residuals, deg, same shape as `snr_db`.
    """
    s = 10.0 ** (np.asarray(snr_db, dtype=float) / 10.0)
    sigma = np.sqrt(floor_deg**2 + spread_deg**2 / (1.0 + s))
    return np.asarray(bias_deg, dtype=float) + sigma * rng.standard_normal(s.shape)


@dataclass(frozen=True)
class AmplitudeScenario:
    """Simulated tracker outputs and their truth, one row per update.

    Attributes
    ----------
    track_id : ndarray of int, shape (m,)
        Track of each update.
    time : ndarray, shape (m,)
        Update time, s.
    amplitude : ndarray, shape (m,)
        Cell power, linear, normalised (noise mean 1).
    residual_deg : ndarray, shape (m,)
        Bearing residual, deg.
    condition : ndarray of str, shape (m,)
        True condition (:data:`CONDITIONS`).
    snr_db : ndarray, shape (m,)
        True per-cell SNR, dB (``-inf`` when lost).
    segment : ndarray of int, shape (m,)
        Index of the segment within its track.
    """

    track_id: NDArray[np.int64]
    time: NDArray[np.float64]
    amplitude: NDArray[np.float64]
    residual_deg: NDArray[np.float64]
    condition: NDArray[np.str_]
    snr_db: NDArray[np.float64]
    segment: NDArray[np.int64]

    @property
    def n_tracks(self) -> int:
        """Number of tracks."""
        return int(np.unique(self.track_id).size)


def simulate_amplitudes(
    *,
    seed: int,
    n_tracks: int = 6,
    segments_per_track: int = 4,
    segment_updates: tuple[int, int] = (40, 80),
    update_period_s: float = 1.0,
    n_looks: int = 1,
    snr0_db: float = 3.0,
    snr1_db: float = 10.0,
    strong_snr_db: float | tuple[float, float] = 15.0,
    near_jitter_db: float = 0.5,
    manoeuvre_bias_deg: float | tuple[float, float] = 2.5,
    segment_s: tuple[float, float] | None = None,
) -> AmplitudeScenario:
    """Tracks passing through strong, near-threshold, manoeuvre and lost segments.

    Every track starts ``strong``; its other segments are drawn from :data:`CONDITIONS` without
    two equal neighbours, with lengths uniform in `segment_updates`.

    Parameters
    ----------
    seed : int
        Seed of ``np.random.default_rng``.
    n_tracks : int, optional
        Number of tracks.
    segments_per_track : int, optional
        Segments per track.
    segment_updates : (int, int), optional
        Inclusive range of segment lengths, updates (unless `segment_s` is given).
    update_period_s : float, optional
        Time between updates, s.
    n_looks : int, optional
        Periodogram looks per cell.
    snr0_db, snr1_db : float, optional
        Design SNRs of the track quality indicator the near-threshold conditions refer to, dB.
    strong_snr_db : float or (float, float), optional
        SNR of strong and manoeuvre segments, dB; an interval draws it per segment (uniform).
    near_jitter_db : float, optional
        Half-width of the uniform jitter of near-threshold SNRs, dB.
    manoeuvre_bias_deg : float or (float, float), optional
        Residual bias during a manoeuvre, deg (sign drawn per segment); an interval draws its
        size per segment (uniform).
    segment_s : (float, float), optional
        Segment lengths in seconds, uniform in this interval and rounded to whole updates (at
        least one); replaces `segment_updates`.

    Returns
    -------
    AmplitudeScenario
    """
    for name, v in (("n_tracks", n_tracks), ("segments_per_track", segments_per_track)):
        if int(v) != v or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    lo, hi = segment_updates
    if int(lo) != lo or int(hi) != hi or not 1 <= lo <= hi:
        raise ValueError(f"segment_updates must be integers 1 <= lo <= hi, got {segment_updates!r}")
    if not np.isfinite(update_period_s) or update_period_s <= 0:
        raise ValueError(f"update_period_s must be positive, got {update_period_s!r}")
    if not np.isfinite(near_jitter_db) or near_jitter_db < 0:
        raise ValueError(f"near_jitter_db must be >= 0, got {near_jitter_db!r}")
    if segment_s is not None and not (np.all(np.isfinite(segment_s))
                                      and 0 < segment_s[0] <= segment_s[1]):
        raise ValueError(f"segment_s must be an interval 0 < lo <= hi, got {segment_s!r}")
    for name, v in (("strong_snr_db", strong_snr_db), ("manoeuvre_bias_deg", manoeuvre_bias_deg)):
        if not (np.all(np.isfinite(v)) and np.ndim(v) in (0, 1) and np.size(v) in (1, 2)):
            raise ValueError(f"{name} must be a number or an interval (lo, hi), got {v!r}")
    rng = np.random.default_rng(seed)
    cols: dict[str, list[NDArray]] = {k: [] for k in ("track_id", "time", "condition", "snr_db",
                                                      "bias", "segment")}
    for tid in range(n_tracks):
        kinds = ["strong"]
        while len(kinds) < segments_per_track:
            choices = [c for c in CONDITIONS if c != kinds[-1]]
            kinds.append(choices[int(rng.integers(len(choices)))])
        t0 = 0
        for j, kind in enumerate(kinds):
            if segment_s is None:
                m = int(rng.integers(lo, hi + 1))
            else:
                m = max(1, int(round(rng.uniform(*segment_s) / update_period_s)))
            strong = _draw(rng, strong_snr_db) if kind in ("strong", "manoeuvre") else 0.0
            snr = condition_snr_db(kind, snr0_db=snr0_db, snr1_db=snr1_db, strong_snr_db=strong)
            if kind.startswith("near"):
                snr += float(rng.uniform(-near_jitter_db, near_jitter_db))
            bias = 0.0
            if kind == "manoeuvre":
                bias = _draw(rng, manoeuvre_bias_deg) * rng.choice([-1.0, 1.0])
            cols["track_id"].append(np.full(m, tid, dtype=np.int64))
            cols["time"].append((t0 + np.arange(m)) * update_period_s)
            cols["condition"].append(np.full(m, kind))
            cols["snr_db"].append(np.full(m, snr))
            cols["bias"].append(np.full(m, bias))
            cols["segment"].append(np.full(m, j, dtype=np.int64))
            t0 += m
    c = {k: np.concatenate(v) for k, v in cols.items()}
    amplitude = draw_amplitudes(c["snr_db"], rng=rng, n_looks=n_looks)
    residual = draw_residuals(c["snr_db"], rng=rng, bias_deg=c["bias"])
    logger.debug("simulated %d updates of %d tracks", amplitude.size, n_tracks)
    return AmplitudeScenario(
        track_id=c["track_id"], time=c["time"], amplitude=amplitude, residual_deg=residual,
        condition=c["condition"].astype(str), snr_db=c["snr_db"], segment=c["segment"],
    )


def varied_settings(seed: int) -> dict:
    """Keyword arguments of :func:`simulate_amplitudes` drawn from :data:`VARIED_RANGES`.

    Parameters
    ----------
    seed : int
        Scenario seed; the settings come from their own generator seeded by ``(seed, 3)``.

    Returns
    -------
    dict
        ``seed``, the update period and segment count drawn, and the intervals of strong SNR,
        manoeuvre bias and segment length (drawn per segment by the simulator).
    """
    rng = np.random.default_rng([int(seed), 3])
    r = VARIED_RANGES
    lo, hi = np.log(r["update_period_s"])
    return {
        "seed": int(seed),
        "update_period_s": float(np.exp(rng.uniform(lo, hi))),
        "segments_per_track": int(rng.integers(int(r["segments_per_track"][0]),
                                               int(r["segments_per_track"][1]) + 1)),
        "near_jitter_db": float(rng.uniform(*r["near_jitter_db"])),
        "strong_snr_db": r["strong_snr_db"],
        "manoeuvre_bias_deg": r["manoeuvre_bias_deg"],
        "segment_s": r["segment_s"],
    }


def write_scenario(out_dir: Path, *, seed: int, vary: bool = False) -> list[Path]:
    """Write ``amplitudes.csv`` (``track_id,time,amplitude,residual``) and ``truth.csv``.

    ``truth.csv`` holds ``track_id,time,condition,snr_linear,segment`` per update (``snr_linear``
    0 when lost).

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).

    Parameters
    ----------
    vary : bool, optional
        Draw the update period, SNR levels, manoeuvre biases and segment lengths from
        :data:`VARIED_RANGES` (:func:`varied_settings`) instead of the defaults of
        :func:`simulate_amplitudes`.
    """
    sc = simulate_amplitudes(**varied_settings(seed)) if vary else simulate_amplitudes(seed=seed)
    out_dir = Path(out_dir)
    amp = write_table(out_dir / "amplitudes.csv", {
        "track_id": sc.track_id, "time": sc.time, "amplitude": sc.amplitude,
        "residual": sc.residual_deg,
    })
    truth = write_table(out_dir / "truth.csv", {
        "track_id": sc.track_id, "time": sc.time, "condition": sc.condition,
        "snr_linear": 10.0 ** (sc.snr_db / 10.0), "segment": sc.segment,
    })
    return [amp, truth]
