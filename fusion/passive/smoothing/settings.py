"""Settings of ``fusion smooth`` fitted to the input bearings when the user gives none.

Every scale of the bearing-rate smoothers comes from the data: the scan period, the bearing
noise, the clutter density, the probability of detection and the bearing acceleration PSD. What
was chosen (and whether it was given or estimated) is one :class:`SmoothSettings`, which the
command prints in one line and writes beside its output.

Estimators, one function each:

- :func:`scan_period` -- the median step between distinct detection times;
- :func:`pair_scatter` -- bearing noise and clutter density of unlabeled detections from the
  differences between detections of consecutive scans (a Gaussian for pairs of one source plus
  a uniform floor for the rest, fitted by expectation-maximisation);
- :func:`second_difference_sigma` -- bearing noise of labelled tracks from second differences;
- :func:`~fusion.passive.smoothing.diffusion.rate_diffusion` and
  :func:`~fusion.passive.smoothing.diffusion.lag_diffusion` (in
  :mod:`~fusion.passive.smoothing.diffusion`, re-exported here) -- bearing acceleration PSD
  from block-wise rate changes, checked against the growth of second differences with the lag;
- :func:`fit_smooth_settings` -- all of them, the user's values kept where given.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import check_radians, wrap_angle
from fusion.passive.smoothing.diffusion import lag_diffusion, rate_diffusion

__all__ = [
    "SmoothSettings",
    "fit_smooth_settings",
    "lag_diffusion",
    "pair_scatter",
    "rate_diffusion",
    "scan_period",
    "second_difference_sigma",
]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Half-width of the bearing window in which detections of consecutive scans are paired, rad.
PAIR_WINDOW = np.radians(10.0)
#: Scans of the crossing test window ``J`` (and of the rate blocks, half of it).
WINDOW_SCANS = 20
#: Largest probability that a track of the estimated detection probability misses as many scans
#: in a row as end it (sets ``max_misses``).
MISS_RUN_PROBABILITY = 0.01
#: Factor by which the lag fit's acceleration PSD must exceed the block rates' one to replace it
#: (beyond the two estimators' spread on short tracks with correlated camera noise, 2.5 at most
#: on the Autoferry scenarios).
LAG_CONSISTENCY = 4.0


@dataclass(frozen=True)
class SmoothSettings:
    """Scales of the smoothers, given or estimated from the input.

    Attributes
    ----------
    period_s : float
        Median step between distinct detection times, s.
    sigma_bearing_deg : float
        Bearing noise standard deviation, deg.
    q_deg2_per_s3 : float
        Bearing acceleration PSD, deg^2/s^3.
    clutter_density : float
        False detections per scan per radian near a track (unlabeled rows).
    p_detect : float
        Probability that a track is detected in a scan (unlabeled rows).
    init_sigma_rate_deg_per_s : float
        Rate standard deviation of a new track, deg/s.
    max_misses : int
        Scans in a row without a detection that end a track of the initial tracker.
    max_gap_scans : int
        Longest gap, in scans, that a segment link may bridge.
    min_length : int
        Fewest detections of a track formed from unlabeled rows.
    estimated : tuple of str
        Names of the attributes estimated from the data (the others were given).
    """

    period_s: float
    sigma_bearing_deg: float
    q_deg2_per_s3: float
    clutter_density: float
    p_detect: float
    init_sigma_rate_deg_per_s: float
    max_misses: int
    max_gap_scans: int
    min_length: int
    estimated: tuple[str, ...] = field(default=())

    def describe(self) -> str:
        """One line: every value, estimated ones marked ``(est.)``."""
        def mark(name: str) -> str:
            return " (est.)" if name in self.estimated else ""
        return (f"K {self.period_s:.4g} s{mark('period_s')}, sigma {self.sigma_bearing_deg:.3g} deg"
                f"{mark('sigma_bearing_deg')}, q {self.q_deg2_per_s3:.3g} deg^2/s^3"
                f"{mark('q_deg2_per_s3')}, clutter {self.clutter_density:.3g} /scan/rad"
                f"{mark('clutter_density')}, P_D {self.p_detect:.2f}{mark('p_detect')}, "
                f"init rate sigma {self.init_sigma_rate_deg_per_s:.3g} deg/s"
                f"{mark('init_sigma_rate_deg_per_s')}, max misses {self.max_misses}, max gap "
                f"{self.max_gap_scans} scans, min length {self.min_length}")

    def as_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict (``estimated`` as a list)."""
        d = asdict(self)
        d["estimated"] = list(self.estimated)
        return d


def scan_period(times: ArrayLike, track_id: ArrayLike | None = None) -> float:
    """Median step between distinct times, s (1.0 with fewer than two distinct times).

    With `track_id`, the steps of every labelled track and of the unknown-origin rows (id < 0)
    are pooled: labelled rows count even when rows of unknown origin exist.

    Examples
    --------
    >>> scan_period([0, 2, 4, 1, 2, 3, 4, 5], [-1, -1, -1, 0, 0, 0, 0, 0])
    1.0
    """
    t = np.asarray(times, float)
    if track_id is None:
        u = np.unique(t)
        return float(np.median(np.diff(u))) if u.size > 1 else 1.0
    ids = np.asarray(track_id)
    steps = [np.diff(np.unique(t[ids < 0]))]
    steps += [np.diff(np.unique(t[ids == k])) for k in np.unique(ids[ids >= 0])]
    d = np.concatenate(steps)
    return float(np.median(d)) if d.size else 1.0


def pair_scatter(
    times: ArrayLike, bearings: ArrayLike, *, window: float = PAIR_WINDOW, max_iterations: int = 200
) -> tuple[float, float, float]:
    """Bearing noise and clutter density from detections of consecutive scans.

    Parameters
    ----------
    times, bearings : array_like, shape (n,)
        Unlabeled detections (:mod:`fusion.passive.smoothing`).
    window : float, keyword-only
        Half-width ``W`` of the pairing window, rad.
    max_iterations : int, keyword-only
        EM iteration cap.

    Returns
    -------
    sigma : float
        Bearing noise standard deviation, rad (``nan`` with fewer than 10 pairs).
    clutter_density : float
        Detections per scan per radian near a source that are not its own (the uniform floor
        around detections that have a partner).
    fraction : float
        Fraction of pairs from one source (the Gaussian's weight).

    Notes
    -----
    Every detection ``i`` of scan ``k`` is paired with every detection ``j`` of scan ``k + 1``
    within ``W``; ``d = wrap(z_j - z_i)``. A source seen in both scans gives ``d ~ N(0, 2
    sigma^2)`` (its bearing change in one scan period is small beside the noise); all other pairs
    spread over ``[-W, W]``. Exact repeats (``d = 0``: a scan sent twice) are left out. The
    mixture ``w N(0, s^2) + (1 - w) / (2 W)`` is fitted by EM
    (responsibilities, then ``w`` and ``s^2`` as weighted means); ``sigma = s / sqrt(2)``; the
    clutter density is the number of other detections within ``W`` of a detection (all its
    pairs but one), averaged with weights = how surely it has a partner (its largest
    responsibility), over ``2 W``.
    """
    t = np.asarray(times, float)
    z = np.asarray(bearings, float)
    scans, scan_of = np.unique(t, return_inverse=True)
    if scans.size < 2:
        return float("nan"), float("nan"), float("nan")
    period = float(np.median(np.diff(scans)))
    order = np.argsort(scan_of, kind="stable")
    starts = np.searchsorted(scan_of[order], np.arange(scans.size + 1))
    d_list, ref_list, n_ref = [], [], 0
    for k in range(scans.size - 1):
        if scans[k + 1] - scans[k] > 1.5 * period:
            continue
        a = z[order[starts[k]: starts[k + 1]]]
        b = z[order[starts[k + 1]: starts[k + 2]]]
        d = wrap_angle(b[None, :] - a[:, None])
        ref = np.broadcast_to(np.arange(n_ref, n_ref + a.size)[:, None], d.shape)
        keep = (np.abs(d) <= window) & (np.abs(d) > 1e-9)  # exact repeats are no new look
        d_list.append(d[keep])
        ref_list.append(ref[keep])
        n_ref += a.size
    d = np.concatenate(d_list) if d_list else np.zeros(0)
    if d.size < 10:
        return float("nan"), float("nan"), float("nan")
    refs = np.concatenate(ref_list)
    s2, w = (window / 10.0) ** 2, 0.5
    r = np.zeros(d.size)
    for _ in range(max_iterations):
        g = w * np.exp(-0.5 * d * d / s2) / np.sqrt(2 * np.pi * s2)
        r = g / (g + (1.0 - w) / (2.0 * window))
        w_new = float(np.mean(r))
        s2_new = float(np.sum(r * d * d) / max(np.sum(r), 1e-12))
        done = abs(w_new - w) < 1e-6 and abs(s2_new - s2) < 1e-6 * s2
        w, s2 = w_new, max(s2_new, 1e-12)
        if done:
            break
    # clutter near a source: the other detections within W of a detection that has a partner
    # (its own source seen again), weighted by how surely it has one, over the window
    track_like = np.zeros(n_ref)
    np.maximum.at(track_like, refs, r)
    others = np.bincount(refs, minlength=n_ref) - 1.0
    clutter = float(np.sum(track_like * np.maximum(others, 0.0))
                    / max(np.sum(track_like), 1e-12)) / (2 * window)
    return float(np.sqrt(s2 / 2.0)), float(clutter), float(w)


def second_difference_sigma(groups: list[tuple[FloatArray, FloatArray]]) -> float:
    """Bearing noise of labelled tracks from second differences, rad.

    Parameters
    ----------
    groups : list of (times, bearings)
        Per track, time-ordered times (s) and bearings (rad).

    Returns
    -------
    float
        ``1.4826 MAD(d2) / sqrt(6)`` pooled over tracks, ``d2_k = z_{k+1} - 2 z_k + z_{k-1}``
        (unwrapped): white noise of standard deviation sigma gives ``var(d2) = 6 sigma^2``;
        a smooth bearing adds little at the sampling rate. ``nan`` with fewer than 3 values.
    """
    d2 = [np.diff(np.unwrap(z), 2) for _, z in groups if z.size >= 3]
    if not d2:
        return float("nan")
    a = np.concatenate(d2)
    if a.size < 3:
        return float("nan")
    return float(1.4826 * np.median(np.abs(a - np.median(a))) / np.sqrt(6.0))


def fit_smooth_settings(
    track_id: ArrayLike,
    times: ArrayLike,
    bearings: ArrayLike,
    *,
    sigma_bearing_deg: float | None = None,
    period_s: float | None = None,
    q_deg2_per_s3: float | None = None,
    clutter_density: float | None = None,
    p_detect: float | None = None,
    init_sigma_rate_deg_per_s: float | None = None,
    max_misses: int | None = None,
    max_gap_scans: int | None = None,
    min_length: int | None = None,
    max_miss_s: float = 4.0,
) -> SmoothSettings:
    """Settings of ``fusion smooth``: the given ones, the others estimated from the rows.

    Parameters
    ----------
    track_id : array_like of int, shape (n,)
        Track of each row, -1 for detections of unknown origin.
    times : array_like, shape (n,)
        Times, s.
    bearings : array_like, shape (n,)
        Bearings, rad (degrees, any ``|value| > 2 pi``, are refused: the options below are in
        the units their names give, the bearings are not a file's ``bearing_deg``).
    sigma_bearing_deg, period_s, q_deg2_per_s3, clutter_density, p_detect, \
init_sigma_rate_deg_per_s, max_misses, max_gap_scans, min_length : optional, keyword-only
        Given values (``None``: estimate); see :class:`SmoothSettings`.
    max_miss_s : float, keyword-only
        A track of the initial tracker survives misses for at least this long, s (sets
        ``max_misses`` with the detection probability; default 4 s: camera detections of a
        boat drop out for seconds when it is hidden or its detector box jumps).

    Returns
    -------
    SmoothSettings

    Notes
    -----
    Order: period; sigma (unlabeled rows: :func:`pair_scatter`, else
    :func:`second_difference_sigma`) with the clutter density; then, for unlabeled rows, one
    pass of :class:`~fusion.passive.smoothing.nearest_neighbour.NearestNeighbourTracker` with a
    generous acceleration PSD (the rate may change by ``sigma / (10 K)`` per scan) gives tracks
    whose hit fraction is ``P_D`` (lower quartile over tracks: the weaker sources must
    survive) and whose block rates (:func:`rate_diffusion`, blocks of ``J/2`` scans: the scale
    of the crossing test) give ``q`` and the rate spread of new tracks; labelled tracks give
    both directly. ``q`` is then checked against the second differences across lags
    (:func:`lag_diffusion`, the noise held at the fitted sigma): where the lags need more than
    ``LAG_CONSISTENCY`` times the block estimate (long, slowly curving tracks whose blocks see
    only noise), the lag estimate is taken. ``max_misses`` is the shortest run of misses
    that a track of detection probability ``P_D`` has with probability below 1 %, and at least
    `max_miss_s`; a link may
    bridge 4 such runs (at least 40 scans); a track needs ``P_D J`` detections (at least 5).
    Fallbacks when the data cannot tell (too few pairs or tracks): the previous fixed defaults
    (0.5 deg, 3e-6 deg^2/s^3, 0.1 /scan/rad, 0.9).
    """
    ids = np.asarray(track_id)
    t = np.asarray(times, float)
    z = check_radians(bearings)
    est: list[str] = []
    if period_s is None:
        period = scan_period(t, ids)
        est.append("period_s")
    else:
        period = float(period_s)
    unk = ids < 0
    order = np.argsort(t[unk], kind="stable")
    tu, zu = t[unk][order], z[unk][order]
    labelled = [(t[ids == k][np.argsort(t[ids == k], kind="stable")],
                 z[ids == k][np.argsort(t[ids == k], kind="stable")])
                for k in np.unique(ids[ids >= 0])]
    sigma_u, clutter_u, _ = pair_scatter(tu, zu) if tu.size else (np.nan, np.nan, np.nan)
    if sigma_bearing_deg is None:
        sig = sigma_u if np.isfinite(sigma_u) else second_difference_sigma(labelled)
        sigma_bearing_deg = float(np.degrees(sig)) if np.isfinite(sig) and sig > 0 else 0.5
        est.append("sigma_bearing_deg")
    if clutter_density is None:
        clutter_density = float(clutter_u) if np.isfinite(clutter_u) and clutter_u > 0 else 0.1
        est.append("clutter_density")
    sigma = float(np.radians(sigma_bearing_deg))
    groups = list(labelled)
    p_est = float("nan")
    if tu.size and (q_deg2_per_s3 is None or p_detect is None
                    or init_sigma_rate_deg_per_s is None):
        from fusion.passive.smoothing.nearest_neighbour import NearestNeighbourTracker

        q0 = (sigma / (10.0 * period)) ** 2 / period
        nn = NearestNeighbourTracker(sigma_bearing=sigma, q=q0, init_sigma_rate=sigma / period,
                                     max_misses=5, window_scans=WINDOW_SCANS).run(tu, zu)
        scan_of = np.searchsorted(nn.scan_times, tu)
        hits = []
        for m in range(nn.n_tracks):
            sel = np.flatnonzero(nn.labels == m)
            if sel.size < 2 * 4:
                continue
            span = int(nn.last_scan[m] - nn.first_scan[m] + 1)
            # scans the track spanned, in periods (empty scans are absent from the data)
            n_periods = (nn.scan_times[nn.last_scan[m]] - nn.scan_times[nn.first_scan[m]]) / period
            hits.append(np.unique(scan_of[sel]).size / max(n_periods + 1.0, span))
            groups.append((tu[sel], zu[sel]))
        if hits:
            p_est = float(np.quantile(hits, 0.25))  # the weaker sources set the track rules
    block = WINDOW_SCANS / 2 * period
    q_rates, rates = rate_diffusion(groups, sigma=sigma, block_s=block)
    q_est = q_rates
    q_lags, _ = lag_diffusion(groups, sigma=sigma)
    if np.isfinite(q_lags) and not q_lags <= LAG_CONSISTENCY * q_rates:
        # the tracks move far more over their lags than the block rates say (long, slowly
        # curving tracks whose blocks see only noise): the block estimate is inconsistent
        q_est = q_lags
    if q_deg2_per_s3 is None:
        # floor: the motion factor over one scan no stiffer than 1e-6 of a bearing factor's
        # variance (q K^3 / 3 >= 1e-6 sigma^2), else the chain is too ill-conditioned to solve
        q_min = 3e-6 * sigma**2 / period**3
        q = q_est if np.isfinite(q_est) else np.radians(1.0) ** 2 * 3e-6
        q_deg2_per_s3 = float(max(q, q_min) / np.radians(1.0) ** 2)
        est.append("q_deg2_per_s3")
    if p_detect is None:
        p_detect = float(np.clip(p_est, 0.05, 0.99)) if np.isfinite(p_est) else 0.9
        est.append("p_detect")
    if init_sigma_rate_deg_per_s is None:
        spread = float(np.quantile(np.abs(rates), 0.95)) if rates.size >= 5 else np.nan
        floor = sigma / (WINDOW_SCANS * period)
        val = max(spread, floor) if np.isfinite(spread) else 0.01
        init_sigma_rate_deg_per_s = float(np.degrees(val))
        est.append("init_sigma_rate_deg_per_s")
    if max_misses is None:
        run = np.log(MISS_RUN_PROBABILITY) / np.log(max(1.0 - p_detect, 1e-9))
        max_misses = int(np.clip(max(np.ceil(run), np.ceil(max_miss_s / period)), 3, 500))
        est.append("max_misses")
    if max_gap_scans is None:
        max_gap_scans = max(40, 4 * int(max_misses))
        est.append("max_gap_scans")
    if min_length is None:
        min_length = max(5, int(np.ceil(p_detect * WINDOW_SCANS)))
        est.append("min_length")
    return SmoothSettings(
        period_s=period, sigma_bearing_deg=float(sigma_bearing_deg),
        q_deg2_per_s3=float(q_deg2_per_s3), clutter_density=float(clutter_density),
        p_detect=float(p_detect), init_sigma_rate_deg_per_s=float(init_sigma_rate_deg_per_s),
        max_misses=int(max_misses), max_gap_scans=int(max_gap_scans), min_length=int(min_length),
        estimated=tuple(est),
    )
