"""Scores of click detections against a simulated scenario's truth (tests and benchmarks only).

A detection is matched, one to one and closest first, to the truth of its channel in this
order: a direct-path arrival (a *hit*), a surface echo (an *echo*: a real click in the audio,
neither a hit nor a false alarm), a transient onset (a *transient*, counted as a false alarm:
the centre-frequency test is meant to remove those it can). Anything else is *false*.
Recall is over direct arrivals; precision is ``(hits + echoes) / detections``. The per-click
SNR of an arrival is ``20 log10(|peak amplitude| / noise_std_band)``, taken from the truth for
scoring only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.types import ChannelClicks
from fusion.simulate.clicks import ClickScenario

__all__ = ["ClickScore", "match_times", "score_clicks"]


@dataclass(frozen=True)
class ClickScore:
    """Detections of one scenario scored against its truth.

    Attributes
    ----------
    n_detections, n_hits, n_echoes, n_transients, n_false : int
        Detections in total and by what they matched.
    direct_snr_db : ndarray, shape (m,)
        Per-click SNR of every scored direct arrival (all channels), dB.
    direct_detected : ndarray of bool, shape (m,)
        Whether each was detected.
    time_errors_s : ndarray, shape (n_hits,)
        Detected minus true time of each hit, s.
    """

    n_detections: int
    n_hits: int
    n_echoes: int
    n_transients: int
    n_false: int
    direct_snr_db: NDArray[np.float64]
    direct_detected: NDArray[np.bool_]
    time_errors_s: NDArray[np.float64]

    @property
    def precision(self) -> float:
        """``(hits + echoes) / detections`` (1 with no detection)."""
        return (self.n_hits + self.n_echoes) / self.n_detections if self.n_detections else 1.0

    def recall(self, min_snr_db: float = -np.inf) -> float:
        """Fraction of direct arrivals with per-click SNR >= `min_snr_db` that were detected."""
        sel = self.direct_snr_db >= min_snr_db
        return float(self.direct_detected[sel].mean()) if sel.any() else float("nan")


def match_times(
    det: NDArray[np.float64], ref: NDArray[np.float64], tol_s: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """One-to-one matching of two time lists within `tol_s`, closest pairs first.

    Returns
    -------
    i_det, i_ref : ndarray of int
        Indices of the matched pairs.
    """
    det, ref = np.asarray(det, dtype=float), np.asarray(ref, dtype=float)
    if det.size == 0 or ref.size == 0:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    order = np.argsort(ref)
    rs = ref[order]
    lo = np.searchsorted(rs, det - tol_s, side="left")
    hi = np.searchsorted(rs, det + tol_s, side="right")
    pairs = [(abs(det[i] - rs[j]), i, j) for i in range(det.size) for j in range(lo[i], hi[i])]
    pairs.sort()
    used_d, used_r, out_d, out_r = set(), set(), [], []
    for _, i, j in pairs:
        if i not in used_d and j not in used_r:
            used_d.add(i)
            used_r.add(j)
            out_d.append(i)
            out_r.append(int(order[j]))
    return np.asarray(out_d, dtype=np.int64), np.asarray(out_r, dtype=np.int64)


def score_clicks(
    clicks: list[ChannelClicks], scenario: ClickScenario, *, tol_s: float = 0.5e-3,
    edge_s: float = 5e-3,
) -> ClickScore:
    """Score detections of every channel against a scenario's truth.

    Parameters
    ----------
    clicks : list of ChannelClicks
        One per channel of the scenario's audio.
    scenario : ClickScenario
        The simulated recording and its truth.
    tol_s : float, optional
        Largest time difference of a match, s.
    edge_s : float, optional
        Truth and detections within this of either end of the audio are ignored, s.

    Returns
    -------
    ClickScore
    """
    if len(clicks) != scenario.n_sensors:
        raise ValueError(f"need {scenario.n_sensors} ChannelClicks, got {len(clicks)}")
    noise = max(scenario.noise_std_band, 1e-300)
    lo_t, hi_t = edge_s, scenario.duration_s - edge_s
    counts = np.zeros(5, dtype=int)
    snrs, found, errs = [], [], []
    for ch, cc in enumerate(clicks):
        t = cc.times_s[(cc.times_s >= lo_t) & (cc.times_s < hi_t)]
        free = np.ones(t.size, dtype=bool)
        counts[0] += t.size
        direct = np.concatenate([s.arrival_times[:, ch] for s in scenario.sources])
        amp = np.concatenate([s.arrival_amplitudes[:, ch] for s in scenario.sources])
        inside = (direct >= lo_t) & (direct < hi_t)
        direct, amp = direct[inside], amp[inside]
        i_d, i_r = match_times(t, direct, tol_s)
        free[i_d] = False
        hit = np.zeros(direct.size, dtype=bool)
        hit[i_r] = True
        counts[1] += i_d.size
        errs.append(t[i_d] - direct[i_r])
        snrs.append(20.0 * np.log10(np.maximum(np.abs(amp), 1e-300) / noise))
        found.append(hit)
        echo = np.concatenate([s.echo_arrival_times[:, ch] for s in scenario.sources])
        tran = scenario.transient_times[scenario.transient_channels == ch] + 0.5 * tol_s
        for slot, ref in ((2, echo), (3, tran)):
            idx = np.flatnonzero(free)
            i_d, _ = match_times(t[idx], ref, tol_s)
            free[idx[i_d]] = False
            counts[slot] += i_d.size
        counts[4] += int(free.sum())
    return ClickScore(
        n_detections=int(counts[0]), n_hits=int(counts[1]), n_echoes=int(counts[2]),
        n_transients=int(counts[3]), n_false=int(counts[4]),
        direct_snr_db=np.concatenate(snrs), direct_detected=np.concatenate(found),
        time_errors_s=np.concatenate(errs),
    )
