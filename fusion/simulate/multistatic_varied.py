"""Varied multistatic scenarios: the same physics as :mod:`fusion.simulate.multistatic` under
other plausible assumptions, drawn per scenario from the seed.

The fixed scenario of :func:`fusion.simulate.multistatic.simulate_multistatic` makes choices a
tracker can quietly come to depend on: range-sum and bearing errors of one size for every
receiver (the tracker's defaults), hotspots that echo from one point on 70 % of the pings of
every receiver, two clutter echoes per receiver and ping, a target whose reported aspect angle is
its true aspect plus noise. Here every such choice is drawn from a range per scenario (and per
receiver where receivers differ in reality), so that a tracker tuned on the fixed scenario meets
assumptions it was not built on:

- 2-5 receivers at 3.5-8 km from the source; ping interval 60-120 s; 22 pings by default.
- **Target**: 3-8 kn (as in the fixed scenario); straight (40 %) or with one or two turns of
  30-150 deg at 0.1-0.3 deg/s (the fixed scenario turns at 0.3 deg/s); its path keeps twice the
  blanking distance from the source (a path over the source would hide it from every receiver
  for several pings, which tests no tracker).
  Each receiver detects it with its own probability ``Pd`` drawn in [0.4, 0.9] (outside the
  direct-blast blanking zone); its SNR is the threshold plus an exponential excess (mean 3-10 dB
  per scenario) plus a specular gain of 0-10 dB near 90 deg equivalent aspect.
- **Contact errors** in the frame of the bistatic ellipse through the contact: along the ellipse
  normal (the range-sum direction) a standard deviation of 50-200 m drawn per receiver; across
  it (along the ellipse) 1 deg times the receiver-contact range. Position errors are drawn in
  metres, so a tracker that assumes errors of range sum and bearing meets a different model.
- **Hotspots**: 3-8 bottom features, each a spread of 0-75 m (standard deviation) around its
  centre. Each receiver sees each feature with its own probability in [0.6, 0.95] and its own
  mean SNR in [15, 28] dB (2 dB fluctuation per echo).
- **Random clutter**: Poisson with a mean of 2-15 per receiver and ping, drawn per receiver,
  uniform over the area, SNR the threshold plus an exponential excess (mean 2-5 dB).
- **Direct blast**: every echo (target, hotspot, clutter) whose range sum exceeds the
  source-receiver distance by less than the blanking distance is lost at that receiver.
- **Classifier score**: Beta distributions whose separation is drawn per scenario (target mean
  0.58-0.75, hotspot mean 0.35-0.5, clutter mean 0.28-0.45, concentration 5-9).
- **Aspect column**: the target's equivalent aspect plus noise of 10-30 deg; uniform in
  [0, 180] for clutter and hotspots. Written for completeness; a tracker must not treat it as a
  measurement unless the user says it is one.

The drawn parameters are returned in :attr:`MultistaticScenario.parameters` (and written to
``truth.json``) for diagnosis; they are truth, not tracker settings.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import NDArray

from fusion.io import Table
from fusion.simulate._multistatic_types import KNOT, MultistaticScenario

__all__ = ["simulate_varied"]

logger = logging.getLogger(__name__)

_COLUMNS = ("event", "time", "x", "y", "snr_db", "score", "aspect_deg", "src_x", "src_y",
            "rcv_x", "rcv_y", "origin", "receiver")


def _turning_track(
    rng: np.random.Generator, n_pings: int, interval: float, *, min_source_range_m: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Target positions and velocities at ping times: straight or with one or two turns.

    Integrated in 1-s steps with a piecewise constant turn rate. The start heading is drawn
    again (up to 100 times) while the path comes closer than `min_source_range_m` to the source
    at the origin, where the direct blast would hide it from every receiver.
    """
    speed = rng.uniform(3.0, 8.0) * KNOT
    start_r = rng.uniform(2500.0, 6000.0)
    start_a = rng.uniform(0.0, 2 * np.pi)
    pos = start_r * np.array([np.sin(start_a), np.cos(start_a)])
    duration = (n_pings - 1) * interval
    n_turns = int(rng.choice([0, 1, 2], p=[0.4, 0.4, 0.2]))
    turns = []                                               # (start s, end s, rate rad/s)
    for i in range(n_turns):
        start = rng.uniform(0.15 + 0.4 * i, 0.45 + 0.4 * i) * duration
        rate = np.radians(rng.uniform(0.1, 0.3)) * rng.choice([-1.0, 1.0])
        total = np.radians(rng.uniform(30.0, 150.0))
        turns.append((start, start + total / abs(rate), rate))
    steps = int(np.ceil(duration)) + 1
    t = np.arange(steps, dtype=float)
    rate_t = np.zeros(steps)
    for a, b, r in turns:
        rate_t[(t >= a) & (t < b)] += r
    turned = np.concatenate([[0.0], np.cumsum(rate_t[:-1])])
    for _ in range(100):
        aim = rng.normal(0.0, 3000.0, 2)
        heading = np.arctan2(*(aim - pos)) + rng.uniform(-0.6, 0.6)  # compass heading, rad
        head = heading + turned
        vel = speed * np.column_stack([np.sin(head), np.cos(head)])
        xy = pos + np.concatenate([np.zeros((1, 2)), np.cumsum(vel[:-1], axis=0)])
        if np.min(np.hypot(xy[:, 0], xy[:, 1])) >= min_source_range_m:
            break
    ping_t = np.arange(n_pings) * interval
    x = np.column_stack([np.interp(ping_t, t, xy[:, 0]), np.interp(ping_t, t, xy[:, 1])])
    v = np.column_stack([np.interp(ping_t, t, vel[:, 0]), np.interp(ping_t, t, vel[:, 1])])
    return x, v


def _ellipse_frame(
    p: NDArray[np.float64], source: NDArray[np.float64], receiver: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Unit normal and tangent of the bistatic ellipse through ``p``, and the receiver range.

    The normal is the gradient direction of the range sum ``|p - s| + |p - r|``: the bisector of
    the unit vectors from source and receiver to ``p``.
    """
    es = (p - source) / max(np.linalg.norm(p - source), 1e-9)
    d = float(np.linalg.norm(p - receiver))
    er = (p - receiver) / max(d, 1e-9)
    g = es + er
    gn = np.linalg.norm(g)
    n = g / gn if gn > 1e-9 else er
    return n, np.array([-n[1], n[0]]), d


def simulate_varied(seed: int, *, n_pings: int = 22, area_half_width_m: float = 10000.0,
                    detection_threshold_db: float = 10.0, blanking_m: float = 1000.0,
                    target_pd: float | None = None,
                    clutter_per_receiver: float | None = None):
    """Simulate one varied multistatic run (see the module docstring for the draws).

    Parameters
    ----------
    seed : int
        Random seed; same seed, same scenario.
    n_pings : int, optional
        Pings (default 22), >= 2.
    area_half_width_m : float, optional
        Clutter and hotspots lie in the square of this half width around the source, m.
    detection_threshold_db : float, optional
        Lowest SNR of a detection, dB.
    blanking_m : float, optional
        Echoes with ``rho - |s - r|`` below this are lost in the direct blast, m.
    target_pd : float, optional
        Every receiver's probability of detecting the target per ping, in (0, 1]; None
        (default): drawn per receiver in [0.4, 0.9]. The draws happen either way, so the rest
        of the scenario is the same as without it.
    clutter_per_receiver : float, optional
        Mean random clutter echoes per receiver and ping, >= 0; None (default): drawn per
        receiver in [2, 15] (drawn either way, as `target_pd`).

    Returns
    -------
    fusion.simulate.multistatic.MultistaticScenario
        With :attr:`parameters` holding the drawn scenario parameters.
    """
    if n_pings < 2:
        raise ValueError(f"n_pings must be >= 2, got {n_pings}")
    if target_pd is not None and not 0.0 < target_pd <= 1.0:
        raise ValueError(f"target_pd must lie in (0, 1], got {target_pd!r}")
    if clutter_per_receiver is not None and not clutter_per_receiver >= 0.0:
        raise ValueError(f"clutter_per_receiver must be >= 0, got {clutter_per_receiver!r}")
    rng = np.random.default_rng(seed)
    n_rx = int(rng.integers(2, 6))
    interval = float(rng.uniform(60.0, 120.0))
    source = np.zeros(2)
    ang = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n_rx) / n_rx + rng.uniform(-0.3, 0.3, n_rx)
    rad = rng.uniform(3500.0, 8000.0, n_rx)
    receivers = np.column_stack([rad * np.sin(ang), rad * np.cos(ang)])
    hw = area_half_width_m
    n_hot = int(rng.integers(3, 9))
    hotspots = rng.uniform(-0.8 * hw, 0.8 * hw, (n_hot, 2))
    hot_spread = rng.uniform(0.0, 75.0, n_hot)
    tgt_x, tgt_v = _turning_track(rng, n_pings, interval, min_source_range_m=2.0 * blanking_m)

    pd_target = rng.uniform(0.4, 0.9, n_rx)
    sigma_normal = rng.uniform(50.0, 200.0, n_rx)
    sigma_across_rad = np.radians(1.0)
    pd_hot = rng.uniform(0.6, 0.95, (n_rx, n_hot))
    snr_hot = rng.uniform(15.0, 28.0, (n_rx, n_hot))
    clutter_rate = rng.uniform(2.0, 15.0, n_rx)
    tgt_excess_db = rng.uniform(3.0, 10.0)
    tgt_specular_db = rng.uniform(0.0, 10.0)
    clutter_excess_db = rng.uniform(2.0, 5.0)
    aspect_noise_deg = rng.uniform(10.0, 30.0)
    conc = rng.uniform(5.0, 9.0)
    if target_pd is not None:
        pd_target = np.full(n_rx, float(target_pd))
    if clutter_per_receiver is not None:
        clutter_rate = np.full(n_rx, float(clutter_per_receiver))
    mean_score = {"target": rng.uniform(0.58, 0.75), "hotspot": rng.uniform(0.35, 0.5),
                  "clutter": rng.uniform(0.28, 0.45)}

    rows: dict[str, list] = {k: [] for k in _COLUMNS}

    def contact(p: NDArray[np.float64], j: int) -> NDArray[np.float64]:
        n, t, d = _ellipse_frame(p, source, receivers[j])
        return (p + n * rng.normal(0.0, sigma_normal[j])
                + t * rng.normal(0.0, sigma_across_rad * d))

    def blanked(p: NDArray[np.float64], j: int) -> bool:
        """Whether an echo from ``p`` reaches receiver ``j`` inside the direct blast."""
        rho = np.linalg.norm(p - source) + np.linalg.norm(p - receivers[j])
        return bool(rho - np.linalg.norm(receivers[j] - source) < blanking_m)

    def score(origin: str) -> float:
        m = mean_score[origin]
        return float(rng.beta(m * conc, (1.0 - m) * conc))

    def add(k: int, xy, snr: float, origin: str, aspect: float, j: int) -> None:
        for key, val in (("event", k), ("time", k * interval), ("x", xy[0]), ("y", xy[1]),
                         ("snr_db", snr), ("score", score(origin)), ("aspect_deg", aspect),
                         ("src_x", source[0]), ("src_y", source[1]),
                         ("rcv_x", receivers[j, 0]), ("rcv_y", receivers[j, 1]),
                         ("origin", origin), ("receiver", j)):
            rows[key].append(val)

    thr = detection_threshold_db
    for k in range(n_pings):
        for j, rcv in enumerate(receivers):
            p, v = tgt_x[k], tgt_v[k]
            if rng.random() < pd_target[j] and not blanked(p, j):
                b = (source - p) / np.linalg.norm(source - p) + (rcv - p) / np.linalg.norm(rcv - p)
                h = v / max(np.linalg.norm(v), 1e-9)
                aspect = np.degrees(np.arccos(np.clip(h @ b / max(np.linalg.norm(b), 1e-9),
                                                      -1, 1)))
                snr = (thr + rng.exponential(tgt_excess_db)
                       + tgt_specular_db * np.exp(-(((aspect - 90.0) / 12.0) ** 2)))
                add(k, contact(p, j), snr, "target",
                    float(np.clip(aspect + rng.normal(0, aspect_noise_deg), 0, 180)), j)
            for h_i, hs in enumerate(hotspots):
                if rng.random() < pd_hot[j, h_i]:
                    spot = hs + rng.normal(0.0, hot_spread[h_i], 2) if hot_spread[h_i] else hs
                    snr = max(rng.normal(snr_hot[j, h_i], 2.0), thr)
                    if not blanked(spot, j):
                        add(k, contact(spot, j), snr, "hotspot", rng.uniform(0, 180), j)
            for _ in range(rng.poisson(clutter_rate[j])):
                spot = rng.uniform(-hw, hw, 2)
                snr = thr + rng.exponential(clutter_excess_db)
                if not blanked(spot, j):
                    add(k, spot, snr, "clutter", rng.uniform(0, 180), j)

    cols = {k: np.asarray(v) for k, v in rows.items()}
    if cols["event"].size == 0:
        cols = {k: np.zeros(0) for k in _COLUMNS}
        cols["origin"] = np.zeros(0, dtype=str)
    cols["event"] = cols["event"].astype(np.int64)
    cols["receiver"] = cols["receiver"].astype(np.int64)
    cols["origin"] = cols["origin"].astype(str)
    truth = Table({
        "event": np.arange(n_pings, dtype=np.int64), "time": np.arange(n_pings) * interval,
        "x": tgt_x[:, 0], "y": tgt_x[:, 1], "vx": tgt_v[:, 0], "vy": tgt_v[:, 1],
    }, f"varied multistatic seed {seed}: truth")
    params = {
        "n_receivers": n_rx, "n_hotspots": n_hot, "ping_interval_s": interval,
        "speed_mps": float(np.hypot(*tgt_v[0])),
        "target_pd": pd_target.tolist(), "sigma_normal_m": sigma_normal.tolist(),
        "sigma_across_deg": 1.0, "hotspot_pd": pd_hot.tolist(), "hotspot_snr_db": snr_hot.tolist(),
        "hotspot_spread_m": hot_spread.tolist(), "clutter_per_receiver": clutter_rate.tolist(),
        "target_snr_excess_db": tgt_excess_db, "target_specular_gain_db": tgt_specular_db,
        "clutter_snr_excess_db": clutter_excess_db, "aspect_noise_deg": aspect_noise_deg,
        "score_mean": mean_score, "score_concentration": conc,
    }
    logger.debug("varied multistatic seed %d: %d receivers, %d detections", seed, n_rx,
                 cols["event"].size)
    return MultistaticScenario(
        detections=Table(cols, f"varied multistatic seed {seed}"), truth=truth, source=source,
        receivers=receivers, hotspots=hotspots, ping_interval_s=interval, seed=seed,
        parameters=params,
    )
