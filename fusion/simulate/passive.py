"""Simulated multi-target passive narrowband cubes: several lines, crossings in bearing, a fade.

The cube is the input of the passive pipeline (:mod:`fusion.pipelines.passive`): ``n_scans``
beam spectra of a line array (beams equally spaced in cosine, beam 0 at forward endfire),
normalised so that noise alone has unit mean, holding several narrowband lines at once. Each
line's bearing moves at a constant rate; lines that share a frequency bin and cross in bearing
merge into one main lobe for a while (the case that swaps track identities); one line fades
out (the case that must end its track as ``lost``).

The building blocks are those of the single-line cube (:mod:`fusion.simulate.cube`): the line's
Gaussian spectrum integrated over bins (:func:`~fusion.simulate.cube.line_spectrum`), the
``sinc^2`` main lobe in cosine space (:func:`~fusion.simulate.cube.beam_pattern`) and the
periodogram looks of all lines summed with independent phases in unit-power noise
(:func:`~fusion.simulate.cube.noisy_power`).

Fade: the per-bin SNR of a fading line falls linearly in dB by ``FADE_DEPTH_DB`` from
``fade_start_s`` to ``fade_end_s`` and the line is absent afterwards. Its truth ``gone_s`` is
the time its SNR falls below 0 dB per bin, from which the delay of a track's end is scored.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import beam_from_bearing
from fusion.io import Cube, write_cube, write_json, write_table
from fusion.simulate.cube import beam_pattern, line_spectrum, noisy_power

__all__ = [
    "FADE_DEPTH_DB",
    "LineTarget",
    "PassiveScenario",
    "random_targets",
    "simulate_passive",
    "write_scenario",
]

logger = logging.getLogger(__name__)

#: SNR drop of a fading line between its fade start and end, dB.
FADE_DEPTH_DB = 30.0

#: Bearings the targets stay within, deg (away from endfire, where beams are wide).
BEARING_LIMITS_DEG = (15.0, 165.0)


@dataclass(frozen=True)
class LineTarget:
    """One narrowband line moving at a constant bearing rate.

    Attributes
    ----------
    bearing0_deg : float
        Bearing from the forward axis at time 0, deg.
    bearing_rate_deg_per_min : float
        Constant bearing rate, deg/min.
    freq_hz : float
        Line frequency, Hz.
    snr_db : float
        Per-bin SNR of the line on the beam steered at it, dB (as in
        :func:`fusion.simulate.cube.simulate_cube`).
    fade_start_s, fade_end_s : float, optional
        The SNR falls by :data:`FADE_DEPTH_DB` dB between these times, s, and the line is absent
        after `fade_end_s`; None: no fade.
    """

    bearing0_deg: float
    bearing_rate_deg_per_min: float
    freq_hz: float
    snr_db: float
    fade_start_s: float | None = None
    fade_end_s: float | None = None

    def __post_init__(self) -> None:
        for name in ("bearing0_deg", "bearing_rate_deg_per_min", "freq_hz", "snr_db"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        if self.freq_hz <= 0:
            raise ValueError(f"freq_hz must be positive, got {self.freq_hz!r}")
        if (self.fade_start_s is None) != (self.fade_end_s is None):
            raise ValueError("give both fade_start_s and fade_end_s, or neither")
        if self.fade_start_s is not None and not self.fade_start_s < self.fade_end_s:
            raise ValueError(
                f"fade_start_s ({self.fade_start_s}) must be before fade_end_s ({self.fade_end_s})")

    def bearing_deg(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """True bearing at times `t` (s), folded into ``[0, 180]`` deg as a line array sees it."""
        theta = np.radians(self.bearing0_deg + self.bearing_rate_deg_per_min * t / 60.0)
        return np.degrees(np.arccos(np.cos(theta)))

    def snr_db_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per-bin SNR at times `t` (s), dB; ``-inf`` where the line is absent."""
        snr = np.full(np.shape(t), float(self.snr_db))
        if self.fade_start_s is None:
            return snr
        frac = (np.asarray(t) - self.fade_start_s) / (self.fade_end_s - self.fade_start_s)
        snr = snr - FADE_DEPTH_DB * np.clip(frac, 0.0, 1.0)
        return np.where(np.asarray(t) > self.fade_end_s, -np.inf, snr)

    @property
    def gone_s(self) -> float:
        """Time the SNR falls below 0 dB per bin, s (``inf`` if it never does)."""
        if self.fade_start_s is None:
            return float("inf")
        span = self.fade_end_s - self.fade_start_s
        return float(self.fade_start_s + np.clip(self.snr_db / FADE_DEPTH_DB, 0.0, 1.0) * span)


@dataclass(frozen=True)
class PassiveScenario:
    """A simulated multi-target cube, the operator's clicks and the ground truth.

    Attributes
    ----------
    cube : fusion.io.Cube
        Power, shape (n_scans, n_beams, n_bins), noise mean 1.
    targets : tuple of LineTarget
        The lines, target ``i`` is ``targets[i]``.
    time : ndarray, shape (n_scans,)
        Scan times, s.
    bearing_deg : ndarray, shape (n_scans, n_targets)
        True bearing of each target at each scan, deg.
    snr_db : ndarray, shape (n_scans, n_targets)
        Per-bin SNR of each line at each scan, dB (``-inf`` when absent).
    bins : ndarray of int, shape (n_targets,)
        Bin nearest each line's frequency.
    clicks : tuple of (int, float, float)
        Operator clicks ``(beam, freq_hz, time_s)``, one per target present at the click scan:
        the beam nearest its bearing and the centre of its bin at that scan.
    crossings : tuple of (int, int, float)
        True crossings ``(target_a, target_b, t_cross)`` of lines in the same bin,
        ``target_a < target_b``, while both are present.
    gone_s : ndarray, shape (n_targets,)
        Time each line's SNR falls below 0 dB per bin, s (``inf`` if never).
    """

    cube: Cube
    targets: tuple[LineTarget, ...]
    time: NDArray[np.float64]
    bearing_deg: NDArray[np.float64]
    snr_db: NDArray[np.float64]
    bins: NDArray[np.int64]
    clicks: tuple[tuple[int, float, float], ...]
    crossings: tuple[tuple[int, int, float], ...]
    gone_s: NDArray[np.float64]

    @property
    def n_targets(self) -> int:
        """Number of lines."""
        return len(self.targets)


def _true_crossings(
    time: NDArray[np.float64], bearing_deg: NDArray[np.float64], present: NDArray[np.bool_],
    bins: NDArray[np.int64],
) -> list[tuple[int, int, float]]:
    """Sign changes of the bearing difference of same-bin lines, interpolated in time."""
    out = []
    n = bearing_deg.shape[1]
    for a in range(n):
        for b in range(a + 1, n):
            if bins[a] != bins[b]:
                continue
            both = present[:, a] & present[:, b]
            sgn = np.sign(bearing_deg[:, a] - bearing_deg[:, b])
            # a strict sign change over a step, or a step onto an exact meeting
            k = np.flatnonzero(both[:-1] & both[1:] & (sgn[:-1] != 0)
                               & ((sgn[:-1] * sgn[1:] < 0) | (sgn[1:] == 0)))
            d = bearing_deg[:, a] - bearing_deg[:, b]
            for i in k:
                frac = d[i] / (d[i] - d[i + 1])
                out.append((a, b, float(time[i] + frac * (time[i + 1] - time[i]))))
    return sorted(out, key=lambda c: c[2])


def simulate_passive(
    *,
    seed: int,
    targets: tuple[LineTarget, ...] | list[LineTarget] | None = None,
    n_scans: int = 400,
    n_beams: int = 64,
    n_bins: int = 32,
    scan_period_s: float = 1.0,
    aperture_m: float = 50.0,
    sound_speed: float = 1500.0,
    first_bin_hz: float = 296.0,
    bin_width_hz: float = 1.0,
    freq_spread_hz: float = 0.15,
    n_averages: int = 1,
    click_scan: int = 59,
    noise: bool = True,
    n_targets: int = 6,
    n_crossing_pairs: int = 2,
    n_fading: int = 1,
) -> PassiveScenario:
    """Simulate a normalised cube with several narrowband lines.

    Parameters
    ----------
    seed : int
        Seed of ``np.random.default_rng`` (the targets, when drawn, and the noise).
    targets : sequence of LineTarget, optional
        The lines; default: drawn by :func:`random_targets` (see `n_targets`).
    n_scans, n_beams, n_bins : int
        Cube shape.
    scan_period_s : float
        Time between scans, s.
    aperture_m, sound_speed : float
        Line-array aperture, m, and sound speed, m/s.
    first_bin_hz, bin_width_hz : float
        Centre of bin 0 and the bin spacing, Hz.
    freq_spread_hz : float
        Standard deviation of each line's Gaussian spectrum, Hz.
    n_averages : int
        Periodogram looks averaged per cell.
    click_scan : int
        Scan at which the operator clicks every line present (the acquisition's latest scan).
    noise : bool
        False: the noise-free expected cube.
    n_targets, n_crossing_pairs, n_fading : int
        Lines drawn when `targets` is None (default 6 lines: two crossing pairs, one fading).

    Returns
    -------
    PassiveScenario

    Examples
    --------
    >>> sc = simulate_passive(seed=0, n_scans=120)
    >>> sc.cube.power.shape, sc.n_targets
    ((120, 64, 32), 6)
    """
    for name, v, least in (("n_scans", n_scans, 2), ("n_beams", n_beams, 2),
                           ("n_bins", n_bins, 2), ("n_averages", n_averages, 1)):
        if int(v) != v or v < least:
            raise ValueError(f"{name} must be an integer >= {least}, got {v!r}")
    if int(click_scan) != click_scan or not 0 <= click_scan < n_scans:
        raise ValueError(f"click_scan must be an integer in [0, {n_scans - 1}], got {click_scan!r}")
    rng = np.random.default_rng(seed)
    freqs = first_bin_hz + bin_width_hz * np.arange(n_bins)
    if targets is None:
        targets = random_targets(rng, n_targets=n_targets, n_crossing_pairs=n_crossing_pairs,
                                 n_fading=n_fading, duration_s=n_scans * scan_period_s,
                                 freqs=freqs)
    targets = tuple(targets)
    if not targets:
        raise ValueError("no targets given")
    time = np.arange(n_scans) * scan_period_s
    bearing = np.column_stack([tg.bearing_deg(time) for tg in targets])
    snr = np.column_stack([tg.snr_db_at(time) for tg in targets])
    signals = []
    for i, tg in enumerate(targets):
        spectrum = line_spectrum(freqs, bin_width_hz=bin_width_hz, line_freq_hz=tg.freq_hz,
                                 freq_spread_hz=freq_spread_hz)
        pattern = beam_pattern(np.radians(bearing[:, i]), n_beams=n_beams, aperture_m=aperture_m,
                               wavelength_m=sound_speed / tg.freq_hz)
        s_lin = 10.0 ** (snr[:, i] / 10.0)  # 0 where the line is absent
        signals.append(s_lin[:, None, None] * pattern[:, :, None] * spectrum[None, None, :])
    power = noisy_power(signals, rng=rng, n_averages=n_averages, noise=noise)
    cube = Cube(power=power, freqs=freqs, scan_period=scan_period_s, aperture=aperture_m,
                sound_speed=sound_speed)
    bins = np.array([int(np.argmin(np.abs(freqs - tg.freq_hz))) for tg in targets], np.int64)
    present = np.isfinite(snr)
    clicks = tuple(
        (int(np.clip(np.floor(beam_from_bearing(np.radians(bearing[click_scan, i]), n_beams)
                              + 0.5), 0, n_beams - 1)),
         float(freqs[bins[i]]), float(time[click_scan]))
        for i in range(len(targets)) if present[click_scan, i]
    )
    crossings = tuple(_true_crossings(time, bearing, present, bins))
    logger.debug("simulated %d lines, %d crossings, cube %s", len(targets), len(crossings),
                 power.shape)
    return PassiveScenario(
        cube=cube, targets=targets, time=time, bearing_deg=bearing, snr_db=snr, bins=bins,
        clicks=clicks, crossings=crossings,
        gone_s=np.array([tg.gone_s for tg in targets], dtype=float),
    )


def _constant_rate_within(b0: float, rate: float, duration_s: float) -> bool:
    lo, hi = BEARING_LIMITS_DEG
    b1 = b0 + rate * duration_s / 60.0
    return lo <= min(b0, b1) and max(b0, b1) <= hi


def random_targets(
    rng: np.random.Generator,
    *,
    n_targets: int,
    n_crossing_pairs: int,
    n_fading: int,
    duration_s: float,
    freqs: NDArray[np.float64],
    snr_db: tuple[float, float] = (6.0, 12.0),
    crossing_rate_deg_per_min: tuple[float, float] = (4.0, 10.0),
    free_rate_deg_per_min: float = 6.0,
    crossing_window: tuple[float, float] = (0.45, 0.7),
    fade_window: tuple[float, float] = (0.5, 0.7),
    fade_duration_s: float = 30.0,
) -> list[LineTarget]:
    """Draw lines: crossing pairs sharing a bin, fading lines and free lines, one bin each.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every draw.
    n_targets : int
        Number of lines (at least ``2 n_crossing_pairs + n_fading``).
    n_crossing_pairs : int
        Pairs of lines in one bin whose bearings cross once, at a time drawn in
        `crossing_window` (fractions of `duration_s`) and a bearing in 50-130 deg, with rates of
        opposite sign and magnitudes drawn in `crossing_rate_deg_per_min`.
    n_fading : int
        Lines that fade out (:data:`FADE_DEPTH_DB` over `fade_duration_s`), starting at a time
        drawn in `fade_window` (fractions of `duration_s`).
    duration_s : float
        Scenario length, s.
    freqs : ndarray, shape (n_bins,)
        Bin centres, Hz; each pair or single line gets its own bin, every other bin from the
        third, and sits within 0.3 bins of the bin centre.
    snr_db : (float, float)
        Range of the per-bin SNRs, dB.
    crossing_rate_deg_per_min : (float, float)
        Range of the crossing lines' rate magnitudes, deg/min.
    free_rate_deg_per_min : float
        Largest rate magnitude of the other lines, deg/min.
    crossing_window, fade_window : (float, float)
        Fractions of the duration where crossings and fades start.
    fade_duration_s : float
        Length of a fade, s.

    Returns
    -------
    list of LineTarget
        Crossing pairs first (``2 i``, ``2 i + 1``), then fading lines, then free lines; every
        line stays within 15-165 deg.
    """
    n_single = n_targets - 2 * n_crossing_pairs
    if n_crossing_pairs < 0 or n_fading < 0 or n_single < n_fading:
        raise ValueError(
            f"{n_targets} targets cannot hold {n_crossing_pairs} crossing pairs and "
            f"{n_fading} fading lines")
    slots = np.arange(2, freqs.size - 2, 2)
    n_slots = n_crossing_pairs + n_single
    if slots.size < n_slots:
        raise ValueError(f"{freqs.size} bins hold {slots.size} line slots, {n_slots} needed")
    chosen = rng.permutation(slots)[:n_slots]
    df = float(freqs[1] - freqs[0])
    freq = freqs[chosen] + rng.uniform(-0.3, 0.3, n_slots) * df
    out: list[LineTarget] = []
    for p in range(n_crossing_pairs):
        while True:
            t_c = rng.uniform(*crossing_window) * duration_s
            b_c = rng.uniform(50.0, 130.0)
            r = rng.uniform(*crossing_rate_deg_per_min, size=2) * np.array([1.0, -1.0])
            r *= rng.choice([-1.0, 1.0])
            b0 = b_c - r * t_c / 60.0
            if all(_constant_rate_within(b, rr, duration_s) for b, rr in zip(b0, r, strict=True)):
                break
        for b, rr in zip(b0, r, strict=True):
            out.append(LineTarget(float(b), float(rr), float(freq[p]),
                                  float(rng.uniform(*snr_db))))
    for j in range(n_single):
        while True:
            b0 = rng.uniform(20.0, 160.0)
            rr = rng.uniform(-free_rate_deg_per_min, free_rate_deg_per_min)
            if _constant_rate_within(b0, rr, duration_s):
                break
        fade = None
        if j < n_fading:
            start = rng.uniform(*fade_window) * duration_s
            fade = (float(start), float(start + fade_duration_s))
        out.append(LineTarget(float(b0), float(rr), float(freq[n_crossing_pairs + j]),
                              float(rng.uniform(*snr_db)),
                              fade_start_s=None if fade is None else fade[0],
                              fade_end_s=None if fade is None else fade[1]))
    return out


def write_scenario(out_dir: Path, *, seed: int) -> list[Path]:
    """Write a multi-target passive scenario: ``cube.npz``, ``clicks.csv``, ``truth.json``.

    Six lines over 400 one-second scans of 64 beams x 32 bins: two crossing pairs, one fading
    line, three free lines; ``clicks.csv`` (``time,beam,freq``) holds an operator click on every
    line at scan 59, the input of ``fusion passive --cube cube.npz --clicks clicks.csv``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = simulate_passive(seed=seed)
    clicks = np.array(sc.clicks, dtype=float).reshape(-1, 3)
    truth = {
        "targets": [
            {"bearing0_deg": t.bearing0_deg, "bearing_rate_deg_per_min": t.bearing_rate_deg_per_min,
             "freq_hz": t.freq_hz, "snr_db": t.snr_db, "fade_start_s": t.fade_start_s,
             "fade_end_s": t.fade_end_s, "gone_s": None if not np.isfinite(g) else g}
            for t, g in zip(sc.targets, sc.gone_s, strict=True)
        ],
        "crossings": [{"target_a": a, "target_b": b, "t_cross": tc} for a, b, tc in sc.crossings],
        "time": sc.time.tolist(),
        "bearing_deg": sc.bearing_deg.T.tolist(),
    }
    return [
        write_cube(out_dir / "cube.npz", sc.cube),
        write_table(out_dir / "clicks.csv", {"time": clicks[:, 2],
                                             "beam": clicks[:, 0].astype(np.int64),
                                             "freq": clicks[:, 1]}),
        write_json(out_dir / "truth.json", truth),
    ]
