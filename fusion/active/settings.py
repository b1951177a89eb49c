"""Tracker scales read from the detections: scatter, speeds, clutter density, scan period.

The tracker's sizes (a detection's position error, the velocity prior of a new track, the
process noise, the clutter map's and the clutter intensity's lengths, the hotspot rule's
"near") depend on the sensor: a sonar's 100-m echoes a minute or two apart, a harbour radar's
few-metre plots every two seconds. When the user does not give them, :func:`track_settings`
reads them from the detections (the first pings of a run are enough) through *chains of
straight-line triplets*:

1. The scan period ``T`` is the median step between the times of scans with detections.
2. For each detection ``b`` of a scan, the detections ``a`` of the scan before and ``c`` of the
   scan after within ``max_speed_mps`` times the time step (default 30 m/s) are paired, and the
   pair with the smallest second difference ``s = w_1 a + w_2 c - b``,
   ``w_1 = dt_2 / (dt_1 + dt_2)``, ``w_2 = dt_1 / (dt_1 + dt_2)``, is kept: ``s`` is zero for
   any object moving at constant velocity, whatever its speed, and each of its coordinates has
   variance ``(1 + w_1^2 + w_2^2) sigma^2`` for detections with ``sigma`` per axis.
3. Triplets link into chains when consecutive triplets share two detections (``(a, b, c)`` then
   ``(b, c, d)``). A chain of at least ``MIN_CHAIN`` triplets is kept as one object (a target,
   a bottom feature, a fixed echo) unless chance explains it: with ``mu`` the density of the
   chance values of ``s`` near zero (the number of ``(a, c)`` pairs over the area their
   weighted positions cover), the nearest of Poisson points lies within ``r`` with probability
   ``1 - exp(-pi mu r^2)``; a chain whose product of these probabilities exceeds ``MAX_CHANCE``
   (1e-3) is dropped.
4. ``sigma`` is the maximum-likelihood scatter of the kept triplets, ``sqrt(mean(|s|^2 /
   ratio) / 2)``: the scan-to-scan scatter of objects, tails (merged or split plots) included.
5. A kept chain moves when its end-to-end velocity is significant (chi-square, 2 degrees of
   freedom, 0.99, against ``sigma sqrt(2) / span``); with at least ``MIN_MOVING`` triplets in
   moving chains, the velocity prior of a new track is ``speed_90 / 2`` per axis, ``speed_90``
   the 90th percentile of their speeds (weighted by length, noise removed in quadrature), so
   that nine moving objects in ten start within two standard deviations of a still start;
   otherwise 3 m/s (the sonar default).
6. The clutter density is the rate of detections outside kept chains, per scan and square
   metre of the bounding box of the detections (reported; the track score estimates its own
   intensity over the field).

The other scales follow: the process noise lets a target change its velocity by the speed
prior over ``MANOEUVRE_SCANS`` (2.5) scans, ``q = v^2 / (2.5 T)`` with ``v`` the speed prior
but at least 3 m/s (slow objects turn too; on the sonar's 60-120 s pings this is the sonar
default 0.03-0.06 m^2/s^3); the clutter map's feature spread ``0.3 sigma``, the hotspot rule's
"near" from ``sigma`` (full) to ``5 sigma`` (none), the clutter intensity's kernel ``10 sigma``
and the start exclusion around hotspot regions ``sigma``: the ratios of the sonar defaults
(100-m errors; 30-m features, 100-500 m, 1000 m) carried to any scatter.

The second difference of a constant-velocity sequence is the classic statistic for the
measurement noise of a tracker (the noise-identification use of residuals of a polynomial fit,
Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
2001, Section 11.6); the chains and the chance test keep clutter out of it.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.stats import chi2

from fusion.active.types import Ping

__all__ = ["Scales", "TrackSettings", "fit_scales", "track_settings"]

logger = logging.getLogger(__name__)

#: Fastest plausible object, m/s (about 60 kn): the search radius of the triplets.
MAX_SPEED_MPS = 30.0
#: Scatter assumed when the data hold too few triplets (the sonar default), m.
FALLBACK_SIGMA_M = 100.0
#: Velocity prior assumed when no object is seen moving (the sonar default), m/s.
FALLBACK_SPEED_SIGMA_MPS = 3.0
#: Fewest object triplets for an estimate.
MIN_TRIPLETS = 10
#: Fewest linked triplets (scans - 2) of a chain that counts as one object.
MIN_CHAIN = 3
#: Fewest triplets of significantly moving chains for a speed estimate.
MIN_MOVING = 30
#: Largest probability that chance forms a chain as straight (chains kept as objects).
MAX_CHANCE = 1e-3
#: Scans over which a target may change its velocity by the speed prior (process noise).
MANOEUVRE_SCANS = 4


@dataclass(frozen=True)
class TrackSettings:
    """Scales of the tracker for one set of detections, with where each came from.

    Attributes
    ----------
    period_s : float
        Scan (ping) period, s: the median step between event times.
    position_sigma_m : float
        Position error per axis of a detection, m (measurement scatter).
    speed_sigma_mps : float
        Standard deviation of each velocity component of a new track, m/s.
    accel_psd : float
        White-acceleration spectral density, m^2/s^3.
    clutter_density : float
        Detections not from recurring objects, per m^2 and scan (reported; the track score
        estimates its own intensity over the field).
    init_exclusion_m : float
        Detections this close to a hotspot region start no track, m.
    feature_sigma_m : float
        Spread of a clutter feature's echo points per axis (clutter map), m.
    hotspot_near_m : tuple of float
        ``(full, none)``: distances to a hotspot where the rule's "near" is 1 and 0, m.
    intensity_bandwidth_m : float
        Kernel of the clutter intensity estimate, m.
    object_triplets : int
        Straight-line triplets judged from one object.
    moving_triplets : int
        Of those, the ones that move significantly.
    source : dict of str to str
        Per setting, ``"data"``, ``"given"``, ``"fallback"`` (too few triplets) or
        ``"tracks"`` (the speed prior from the confirmed tracks of a pilot run,
        :meth:`with_track_speed`).
    speed_tracks : int
        Tracks whose speeds gave the speed prior (0: it did not come from tracks).
    """

    period_s: float
    position_sigma_m: float
    speed_sigma_mps: float
    accel_psd: float
    clutter_density: float
    init_exclusion_m: float
    feature_sigma_m: float
    hotspot_near_m: tuple[float, float]
    intensity_bandwidth_m: float
    object_triplets: int
    moving_triplets: int
    source: dict[str, str]
    speed_tracks: int = 0

    def with_track_speed(self, speed_sigma_mps: float, tracks: int) -> TrackSettings:
        """These settings with the speed prior measured on confirmed tracks
        (:func:`fusion.active.pilot.pilot_speed_prior`); the process noise follows it by the
        same rule as from triplets, unless it was given. A given speed prior stays."""
        if self.source.get("speed_sigma_mps") == "given":
            return self
        source = dict(self.source, speed_sigma_mps="tracks")
        q = self.accel_psd
        if source.get("accel_psd") != "given":
            q = max(speed_sigma_mps, FALLBACK_SPEED_SIGMA_MPS) ** 2 / (MANOEUVRE_SCANS
                                                                       * self.period_s)
            source["accel_psd"] = "tracks"
        return replace(self, speed_sigma_mps=float(speed_sigma_mps), accel_psd=float(q),
                       source=source, speed_tracks=int(tracks))

    def describe(self) -> str:
        """One line saying what was chosen (``*`` marks a setting given by the user, ``?`` a
        fallback for want of data)."""
        def mark(name: str) -> str:
            return {"given": "*", "fallback": "?",
                    "tracks": (f" (from {self.speed_tracks} confirmed track(s))"
                               if name == "speed_sigma_mps" else "")}.get(
                        self.source.get(name, "data"), "")

        return (f"scan period {self.period_s:.4g} s, position sigma "
                f"{self.position_sigma_m:.3g} m{mark('position_sigma_m')}, speed sigma "
                f"{self.speed_sigma_mps:.3g} m/s{mark('speed_sigma_mps')}, accel psd "
                f"{self.accel_psd:.3g} m^2/s^3{mark('accel_psd')}, clutter "
                f"{self.clutter_density:.3g} /m^2/scan, start exclusion "
                f"{self.init_exclusion_m:.3g} m{mark('init_exclusion_m')} "
                f"({self.object_triplets} object triplets, {self.moving_triplets} moving)")

    def tracker_options(self) -> dict[str, object]:
        """Keyword arguments of :class:`fusion.active.tracker.Tracker` for these scales: the
        sizes above, the density clutter map and the default rule base with this "near"."""
        from fusion.active.clutter import DensityClutterMap
        from fusion.active.rulebase import default_association_system

        return {
            "position_sigma_m": self.position_sigma_m,
            "speed_sigma_mps": self.speed_sigma_mps,
            "accel_psd": self.accel_psd,
            "init_exclusion_m": self.init_exclusion_m,
            "intensity_bandwidth_m": self.intensity_bandwidth_m,
            "clutter_map": DensityClutterMap(position_sigma_m=self.position_sigma_m,
                                             feature_sigma_m=self.feature_sigma_m),
            "system": default_association_system(hotspot_near_m=self.hotspot_near_m),
        }

    def metadata(self) -> dict[str, object]:
        """The settings as plain JSON-ready values."""
        d = asdict(self)
        d["hotspot_near_m"] = list(self.hotspot_near_m)
        return d


@dataclass(frozen=True)
class Scales:
    """What :func:`fit_scales` reads from the detections (None: the data cannot tell).

    Attributes
    ----------
    period_s : float
        Median step between scan times, s (NaN with fewer than two scans).
    sigma_m : float or None
        Scatter per axis of the kept chains' detections, m.
    speed_sigma_mps : float or None
        Half the 90th-percentile speed of moving chains, m/s.
    clutter_density : float
        Detections outside kept chains per scan and m^2.
    object_triplets, moving_triplets : int
        Triplets in kept chains, and in those that move.
    """

    period_s: float
    sigma_m: float | None
    speed_sigma_mps: float | None
    clutter_density: float
    object_triplets: int
    moving_triplets: int


def _triplets(pings: Sequence[Ping], max_speed_mps: float) -> NDArray[np.float64]:
    """Best straight-line triplet of every detection with neighbours on both sides.

    Returns one row per triplet: ``k, ib, ia, ic`` (scan of the middle detection and the
    indices of ``b``, ``a``, ``c`` in their scans), ``r = |s|`` (m), ``ratio`` (variance of
    each coordinate of ``s`` over ``sigma^2``) and ``mu`` (intensity of chance values of ``s``
    near 0 given the candidates, per m^2).
    """
    rows: list[tuple[float, ...]] = []
    trees = [cKDTree(p.xy) for p in pings]
    for k in range(1, len(pings) - 1):
        a, b, c = pings[k - 1], pings[k], pings[k + 1]
        dt1, dt2 = b.time - a.time, c.time - b.time
        if dt1 <= 0 or dt2 <= 0:
            continue
        w1, w2 = dt2 / (dt1 + dt2), dt1 / (dt1 + dt2)
        rho = max_speed_mps * dt1 * dt2 / (dt1 + dt2)      # radius of w1 (a - b), w2 (c - b)
        near_a = trees[k - 1].query_ball_point(b.xy, max_speed_mps * dt1)
        near_c = trees[k + 1].query_ball_point(b.xy, max_speed_mps * dt2)
        for j in range(b.n):
            ia, ic = near_a[j], near_c[j]
            if not ia or not ic:
                continue
            # s = w1 a + w2 c - b: zero for constant velocity, whatever the speed.
            s = w1 * a.xy[ia][:, None, :] + w2 * c.xy[ic][None, :, :] - b.xy[j]
            r2 = np.einsum("ijk,ijk->ij", s, s)
            i, m = np.unravel_index(int(np.argmin(r2)), r2.shape)
            # Chance: the nearest of len(ia) len(ic) values of s spread over the disc of
            # radius 2 rho (density 1 / (pi rho^2) near 0 for two uniform discs of radius rho).
            mu = len(ia) * len(ic) / (np.pi * rho * rho)
            rows.append((k, j, ia[i], ic[m], float(np.sqrt(r2[i, m])),
                         1.0 + w1 * w1 + w2 * w2, mu))
    return np.asarray(rows, dtype=float).reshape(-1, 7)


def _chains(tri: NDArray[np.float64]) -> list[NDArray[np.int64]]:
    """Chains of linked triplets: triplet (a, b, c) at scan k and (b, c, d) at scan k + 1
    agree on both shared detections. Returns each chain's rows of `tri`, in scan order."""
    key = {(int(k), int(j)): n for n, (k, j) in enumerate(tri[:, :2])}
    nxt = {}
    for n, (k, j, _ia, ic) in enumerate(tri[:, :4].astype(int).tolist()):
        m = key.get((k + 1, ic))
        if m is not None and int(tri[m, 2]) == j:
            nxt[n] = m
    heads = set(nxt) - set(nxt.values())
    chains = []
    for h in sorted(heads):
        c = [h]
        while c[-1] in nxt:
            c.append(nxt[c[-1]])
        chains.append(np.asarray(c, dtype=np.int64))
    return chains


def fit_scales(pings: Sequence[Ping], *, max_speed_mps: float = MAX_SPEED_MPS,
               min_chain: int = MIN_CHAIN) -> Scales:
    """Scan period, scatter, speed prior and clutter density of a run.

    Parameters
    ----------
    pings : sequence of Ping
        The run (or its first pings), in time order.
    max_speed_mps : float, optional
        Fastest plausible object, m/s: the search radius per second of the triplets.
    min_chain : int, optional
        Fewest linked triplets of a chain kept as an object (default 3: five scans).

    Returns
    -------
    Scales

    Notes
    -----
    Steps 1-6 of the module docstring.
    """
    scans = [p for p in pings if p.n]
    times = np.array([p.time for p in scans], dtype=float)
    steps = np.diff(np.unique(times))
    period = float(np.median(steps)) if steps.size else float("nan")
    tri = _triplets(scans, max_speed_mps)
    chains = []
    for c in _chains(tri):
        # Probability that chance alone gives every triplet of the chain an |s| as small.
        p_chance = -np.expm1(-np.pi * tri[c, 6] * tri[c, 4] ** 2)   # 1 - exp(-pi mu r^2)
        log_chance = float(np.sum(np.log(np.maximum(p_chance, 1e-300))))
        if c.size >= min_chain and log_chance <= np.log(MAX_CHANCE):
            chains.append(c)
    sigma = speed = None
    n_obj = sum(c.size for c in chains)
    n_mov = 0
    if n_obj >= MIN_TRIPLETS:
        rows = np.concatenate(chains)
        # Each coordinate of s has variance ratio * sigma^2: ML over the chained triplets.
        sigma = float(np.sqrt(np.mean(tri[rows, 4] ** 2 / tri[rows, 5]) / 2.0))
        speeds, weights = [], []
        for c in chains:
            k0, j0 = int(tri[c[0], 0]) - 1, int(tri[c[0], 2])
            k1, j1 = int(tri[c[-1], 0]) + 1, int(tri[c[-1], 3])
            span = scans[k1].time - scans[k0].time
            v = (scans[k1].xy[j1] - scans[k0].xy[j0]) / span
            v_err2 = 2.0 * sigma**2 / span**2                  # per axis
            sp2 = float(v @ v)
            if sp2 > chi2.ppf(0.99, 2) * v_err2:
                speeds.append(np.sqrt(max(sp2 - 2.0 * v_err2, 0.0)))
                weights.append(c.size)
        n_mov = int(np.sum(weights)) if weights else 0
        if n_mov >= MIN_MOVING:
            order = np.argsort(speeds)
            cum = np.cumsum(np.asarray(weights, dtype=float)[order])
            v90 = float(np.asarray(speeds)[order][np.searchsorted(cum, 0.9 * cum[-1])])
            speed = v90 / 2.0
    xy = np.concatenate([p.xy for p in scans]) if scans else np.zeros((0, 2))
    area = float(np.prod(np.maximum(np.ptp(xy, axis=0), 1.0))) if xy.size else 1.0
    n_clutter = xy.shape[0] - n_obj
    return Scales(period_s=period, sigma_m=sigma, speed_sigma_mps=speed,
                   clutter_density=max(n_clutter, 0) / max(len(scans), 1) / area,
                   object_triplets=n_obj, moving_triplets=n_mov)


def track_settings(
    pings: Sequence[Ping],
    *,
    position_sigma_m: float | None = None,
    speed_sigma_mps: float | None = None,
    accel_psd: float | None = None,
    init_exclusion_m: float | None = None,
    feature_sigma_m: float | None = None,
    hotspot_near_m: tuple[float, float] | None = None,
    intensity_bandwidth_m: float | None = None,
    max_speed_mps: float = MAX_SPEED_MPS,
) -> TrackSettings:
    """The tracker's scales for a run: those given, the others read from the detections.

    Parameters
    ----------
    pings : sequence of Ping
        The run (or its first pings), in time order.
    position_sigma_m, speed_sigma_mps, accel_psd, init_exclusion_m : float, optional
        Settings the user gives (m, m/s, m^2/s^3, m); None: from the data.
    feature_sigma_m, intensity_bandwidth_m : float, optional
        Given lengths, m; None: 0.3 and 10 times the position sigma.
    hotspot_near_m : (float, float), optional
        Given "near" of the hotspot rule, m; None: 1 and 5 times the position sigma.
    max_speed_mps : float, optional
        Fastest plausible object, m/s (default 30): the triplet search radius per second.

    Returns
    -------
    TrackSettings

    Notes
    -----
    See the module docstring. With too few straight-line triplets (fewer than ten), the
    scatter falls back to 100 m and the speed prior to 3 m/s (the sonar defaults), marked
    ``fallback`` in :attr:`TrackSettings.source`.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> pings = [Ping(k, 2.0 * k, np.vstack([[3.0 * 2 * k, 0.0] + rng.normal(0, 5, 2),
    ...                                       rng.uniform(-500, 500, (2, 2))]))
    ...          for k in range(60)]
    >>> st = track_settings(pings)
    >>> st.period_s, bool(3.0 < st.position_sigma_m < 8.0)
    (2.0, True)
    """
    if not np.isfinite(max_speed_mps) or max_speed_mps <= 0:
        raise ValueError(f"max_speed_mps must be positive, got {max_speed_mps!r}")
    for name, v in (("position_sigma_m", position_sigma_m), ("speed_sigma_mps", speed_sigma_mps),
                    ("intensity_bandwidth_m", intensity_bandwidth_m)):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v!r}")
    for name, v in (("accel_psd", accel_psd), ("init_exclusion_m", init_exclusion_m),
                    ("feature_sigma_m", feature_sigma_m)):
        if v is not None and not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a number >= 0, got {v!r}")
    if hotspot_near_m is not None and not (0.0 <= hotspot_near_m[0] < hotspot_near_m[1]
                                           and np.isfinite(hotspot_near_m[1])):
        raise ValueError(f"hotspot_near_m must be (full, none) with 0 <= full < none, got "
                         f"{hotspot_near_m!r}")
    sc = fit_scales(pings, max_speed_mps=max_speed_mps)
    source: dict[str, str] = {}

    def pick(name: str, given: float | None, data: float | None, fallback: float) -> float:
        if given is not None:
            source[name] = "given"
            return float(given)
        if data is None or not np.isfinite(data) or data <= 0:
            source[name] = "fallback"
            return float(fallback)
        source[name] = "data"
        return float(data)

    period = sc.period_s if np.isfinite(sc.period_s) and sc.period_s > 0 else 1.0
    sigma = pick("position_sigma_m", position_sigma_m, sc.sigma_m, FALLBACK_SIGMA_M)
    speed = pick("speed_sigma_mps", speed_sigma_mps, sc.speed_sigma_mps,
                 FALLBACK_SPEED_SIGMA_MPS)
    # Slow objects turn too: the manoeuvre allowance assumes at least the fallback speed.
    v_man = max(speed, FALLBACK_SPEED_SIGMA_MPS)
    q = pick("accel_psd", accel_psd, v_man**2 / (MANOEUVRE_SCANS * period), 0.04)
    if source["accel_psd"] == "data" and source["speed_sigma_mps"] != "data":
        source["accel_psd"] = source["speed_sigma_mps"]       # from a given/fallback speed
    excl = pick("init_exclusion_m", init_exclusion_m, sigma, sigma)
    feat = pick("feature_sigma_m", feature_sigma_m, 0.3 * sigma, 0.3 * sigma)
    bw = pick("intensity_bandwidth_m", intensity_bandwidth_m, 10.0 * sigma, 10.0 * sigma)
    source["hotspot_near_m"] = "data" if hotspot_near_m is None else "given"
    near = (sigma, 5.0 * sigma) if hotspot_near_m is None else tuple(map(float, hotspot_near_m))
    for name in ("init_exclusion_m", "feature_sigma_m", "intensity_bandwidth_m",
                 "hotspot_near_m"):
        if source[name] == "data" and source["position_sigma_m"] != "data":
            source[name] = source["position_sigma_m"]      # scaled from a given/fallback sigma
    st = TrackSettings(
        period_s=float(period), position_sigma_m=sigma, speed_sigma_mps=speed, accel_psd=q,
        clutter_density=float(sc.clutter_density), init_exclusion_m=excl,
        feature_sigma_m=feat, hotspot_near_m=(near[0], near[1]),
        intensity_bandwidth_m=bw, object_triplets=sc.object_triplets,
        moving_triplets=sc.moving_triplets, source=source)
    logger.info("track settings: %s", st.describe())
    return st
