"""Ground truth of bearing scenarios: the scenario record and every true crossing of two tracks."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from fusion.geometry import wrap_angle

__all__ = ["BearingScenario", "TrueCrossing", "find_true_crossings"]


class TrueCrossing(NamedTuple):
    """A true bearing crossing of two tracks.

    Attributes
    ----------
    track_a, track_b : int
        Track ids, ``track_a < track_b``.
    t_cross : float
        Time at which the two true bearings are equal, s.
    """

    track_a: int
    track_b: int
    t_cross: float


@dataclass(frozen=True)
class BearingScenario:
    """Bearing measurements of several tracks and their ground truth.

    Attributes
    ----------
    track_id : ndarray of int64, shape (m,)
        Track of each measurement; -1 marks a detection of unknown origin (clutter).
    time : ndarray, shape (m,)
        Measurement times, s (rows sorted by time, then track id).
    bearing_deg : ndarray, shape (m,)
        Measured bearings, deg clockwise from north, in [0, 360).
    true_bearing_deg : ndarray, shape (m,)
        True bearing of each row's target, deg in [0, 360); NaN for clutter rows.
    track_ids : ndarray of int64, shape (n_tracks,)
        Ids of the tracks (0 .. n_tracks - 1).
    truth_time : ndarray, shape (n_t,)
        Sample times, s (``k * sample_period_s``).
    truth_bearing_deg : ndarray, shape (n_tracks, n_t)
        True bearing of each track at each sample time, deg in [0, 360).
    truth_bearing_rate_deg_per_s : ndarray, shape (n_tracks, n_t)
        True bearing rate, deg/s.
    ownship_xy : ndarray, shape (n_t, 2)
        Platform positions, m (x east, y north).
    target_xy : ndarray, shape (n_tracks, n_t, 2)
        Target positions, m.
    crossings : tuple of TrueCrossing
        Every true crossing of any two tracks within ``[0, duration_s]``, sorted by time.
    non_crossing_pairs : tuple of (int, int)
        Pairs ``(a, b)``, ``a < b``, whose bearings never cross within ``[0, duration_s]``.
    near_miss_pairs : tuple of (int, int)
        Planned pairs that come close (``min_miss_deg`` .. ``max_miss_deg``) but never cross.
    parallel_pairs : tuple of (int, int)
        Planned pairs with exactly equal bearing rates at all times.
    planned_crossing_pairs : tuple of (int, int)
        Pairs built to cross (their crossings are in `crossings`).
    planned_crossings : tuple of TrueCrossing
        The crossing each planned pair was built for (a pair may cross again elsewhere).
    sample_period_s : float
        Sample period K, s.
    noise_deg : float
        Standard deviation of the bearing noise, deg (the median over tracks when it differs
        between tracks).
    duration_s : float
        Scenario length, s.
    seed : int
        Seed that produced the scenario.
    track_noise_deg : ndarray, shape (n_tracks,)
        Standard deviation of each track's bearing noise, deg.
    crossing_rate_diff_deg_per_min : tuple of float
        Bearing rate of ``track_b`` minus that of ``track_a`` at each of `crossings`, deg/min.
    gaps : tuple of (int, float, float)
        Spans ``(track, start_s, end_s)`` in which a track was not measured.
    """

    track_id: NDArray[np.int64]
    time: NDArray[np.float64]
    bearing_deg: NDArray[np.float64]
    true_bearing_deg: NDArray[np.float64]
    track_ids: NDArray[np.int64]
    truth_time: NDArray[np.float64]
    truth_bearing_deg: NDArray[np.float64]
    truth_bearing_rate_deg_per_s: NDArray[np.float64]
    ownship_xy: NDArray[np.float64]
    target_xy: NDArray[np.float64]
    crossings: tuple[TrueCrossing, ...]
    non_crossing_pairs: tuple[tuple[int, int], ...]
    near_miss_pairs: tuple[tuple[int, int], ...]
    parallel_pairs: tuple[tuple[int, int], ...]
    planned_crossing_pairs: tuple[tuple[int, int], ...]
    planned_crossings: tuple[TrueCrossing, ...]
    sample_period_s: float
    noise_deg: float
    duration_s: float
    seed: int
    track_noise_deg: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    crossing_rate_diff_deg_per_min: tuple[float, ...] = ()
    gaps: tuple[tuple[int, float, float], ...] = ()

    @property
    def n_tracks(self) -> int:
        """Number of tracks."""
        return int(self.track_ids.size)


def find_true_crossings(
    motions_bearing: Sequence[Callable[[NDArray[np.float64]], NDArray[np.float64]]],
    *,
    duration_s: float,
    step_s: float,
) -> list[TrueCrossing]:
    """Every time two bearing functions become equal (mod 360 deg) within ``[0, duration_s]``.

    Parameters
    ----------
    motions_bearing : list of callable
        ``f_k(t) -> bearing`` (rad) for each track ``k``, vectorised over a 1-D time array.
    duration_s : float
        End of the search interval, s.
    step_s : float
        Grid step of the search, s; each sign change of the wrapped bearing difference on the
        grid is refined with Brent's method. Sign changes where the difference jumps across
        +-180 deg (tracks on opposite bearings) are not crossings and are skipped.

    Returns
    -------
    list of TrueCrossing
        Sorted by time.
    """
    grid = np.linspace(0.0, duration_s, int(np.ceil(duration_s / step_s)) + 1)
    theta = np.array([f(grid) for f in motions_bearing])  # (n, n_grid) rad
    out: list[TrueCrossing] = []
    n = len(motions_bearing)
    for a in range(n):
        for b in range(a + 1, n):
            d = np.asarray(wrap_angle(theta[b] - theta[a]))
            pos = d >= 0.0
            k = np.flatnonzero((pos[:-1] != pos[1:]) & (np.abs(d[:-1]) < np.pi / 2)
                               & (np.abs(d[1:]) < np.pi / 2))
            fa, fb = motions_bearing[a], motions_bearing[b]

            def diff(t: float, fa=fa, fb=fb) -> float:
                return float(wrap_angle(fb(np.array([t]))[0] - fa(np.array([t]))[0]))

            for j in k:
                if d[j] == 0.0:
                    tc = float(grid[j])
                else:
                    tc = float(brentq(diff, grid[j], grid[j + 1], xtol=1e-9))
                out.append(TrueCrossing(a, b, tc))
    out.sort(key=lambda c: (c.t_cross, c.track_a, c.track_b))
    return out
