"""Seeded multistatic active sonar scenario: one submarine, bottom hotspots and random clutter.

The scenario follows the exercise described in "Target tracking using fuzzy logic association"
(Section 7: twenty-two events in shallow water, several detections per event after
classification): one source and 2-4 receivers at fixed, recorded positions ping every
``ping_interval_s``; a submarine moves at constant velocity with one turn; fixed bathymetric
features (hotspots) echo on most pings; random clutter arrives as a Poisson process.

Per ping and receiver:

- **SNR** from a simple bistatic sonar equation (dB)
  ``SNR = FOM - TL(R_s) - TL(R_r) + TS(aspect)``, ``TL(R) = 20 log10(R / 1 m) + alpha R``,
  with ``R_s``, ``R_r`` the source-target and target-receiver ranges and an aspect-dependent
  target strength ``TS = TS_0 + TS_spec exp(-((aspect - 90) / 12)^2)`` (strong near the specular
  equivalent aspect of 90 deg, see :func:`fusion.active.bistatic.equivalent_aspect_deg`); the
  measured SNR adds Gaussian fluctuation, and a detection is made when it reaches the
  detection threshold (so the probability of detection follows the SNR).
- **Position** from the bistatic range sum ``rho = R_s + R_r`` and the bearing ``theta`` at the
  receiver, both with Gaussian errors (:func:`bistatic_position` solves the ellipse-bearing
  intersection). Echoes within ``blanking_m`` of the direct blast (``rho - |s - r|`` small) are
  lost, as in a real receiver.
- **Classifier score** in [0, 1]: Beta distributions, higher on average for the target than for
  clutter, overlapping.
- **Equivalent aspect angle**: the true one plus noise for the target; for clutter no true
  heading exists and the value is uniform in [0, 180]. This column carries the target's truth:
  the tracker ignores it unless told it is a measurement (``Tracker(aspect="measured")``,
  ``fusion track --aspect-column measured``).
- **Hotspots**: strong (high-SNR), low-ish scores, at fixed places, echoing on a given ping and
  receiver with probability ``hotspot_return_probability``.
- **Random clutter**: Poisson number per receiver, uniform over the area, SNR just above the
  threshold.

Truth: the target state at every ping and the origin of each detection
(``target``/``hotspot``/``clutter``).

``vary=True`` draws the scenario's assumptions instead
(:mod:`fusion.simulate.multistatic_varied`); scoring against the truth is in
:mod:`fusion.metrics.multistatic` (``score_tracks``, ``TrackScore``; their old import path here
warns and forwards for one release).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._deprecated import moved_names
from fusion.io import Table, write_json, write_table
from fusion.simulate._multistatic_types import KNOT, MultistaticScenario
from fusion.simulate.multistatic_varied import simulate_varied

__all__ = [
    "MultistaticScenario",
    "bistatic_position",
    "simulate_multistatic",
    "write_scenario",
]

logger = logging.getLogger(__name__)

#: Scores against the truth, moved to :mod:`fusion.metrics.multistatic`; served here with a
#: DeprecationWarning for one release.
__getattr__ = moved_names(__name__, "fusion.metrics.multistatic", ["TrackScore", "score_tracks"],
                          shown="fusion.metrics.multistatic")


def bistatic_position(
    source: ArrayLike, receiver: ArrayLike, range_sum: ArrayLike, bearing: ArrayLike
) -> NDArray[np.float64]:
    """Echo position from the bistatic range sum and the bearing at the receiver.

    Parameters
    ----------
    source, receiver : array_like, shape (..., 2)
        Positions (x east, y north), m.
    range_sum : array_like, shape (...)
        ``|p - s| + |p - r|``, m; must exceed ``|s - r|``.
    bearing : array_like, shape (...)
        Compass bearing from the receiver to the echo, radians clockwise from north.

    Returns
    -------
    ndarray, shape (..., 2)
        ``p = r + d u`` with ``u = (sin theta, cos theta)`` and
        ``d = (rho^2 - |v|^2) / (2 (rho + v . u))``, ``v = r - s`` (the point of the ellipse with
        foci s, r and major axis rho on the bearing line).

    Examples
    --------
    >>> bistatic_position([0, 0], [0, 0], 2000.0, 0.0).tolist()
    [0.0, 1000.0]
    """
    s = np.asarray(source, dtype=float)
    r = np.asarray(receiver, dtype=float)
    rho = np.asarray(range_sum, dtype=float)
    th = np.asarray(bearing, dtype=float)
    u = np.stack([np.sin(th), np.cos(th)], axis=-1)
    v = r - s
    d = (rho**2 - np.sum(v * v, axis=-1)) / (2.0 * (rho + np.sum(v * u, axis=-1)))
    return r + d[..., None] * u


def _target_track(
    rng: np.random.Generator, n_pings: int, interval: float, speed: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Positions and velocities at ping times: constant velocity, one turn (1 s integration)."""
    start_r = rng.uniform(2500.0, 5000.0)
    start_a = rng.uniform(0.0, 2 * np.pi)
    pos = start_r * np.array([np.sin(start_a), np.cos(start_a)])
    # Head roughly across the field, towards a point near the source.
    aim = rng.normal(0.0, 1500.0, 2)
    heading = np.arctan2(*(aim - pos)) + rng.uniform(-0.5, 0.5)  # compass heading, rad
    turn_at = rng.uniform(0.35, 0.6) * n_pings * interval
    turn_total = np.radians(rng.uniform(45.0, 120.0)) * rng.choice([-1.0, 1.0])
    turn_rate = np.radians(0.3) * np.sign(turn_total)              # 0.3 deg/s
    turn_end = turn_at + turn_total / turn_rate
    t_end = (n_pings - 1) * interval
    ping_t = np.arange(n_pings) * interval
    xs, vs = [], []
    t, k = 0.0, 0
    while k < n_pings:
        vel = speed * np.array([np.sin(heading), np.cos(heading)])
        if t >= ping_t[k] - 1e-9:
            xs.append(pos.copy())
            vs.append(vel)
            k += 1
            continue
        if turn_at <= t < turn_end:
            heading += turn_rate
        pos = pos + vel
        t += 1.0
        if t > t_end + 1:
            break
    return np.array(xs), np.array(vs)


def simulate_multistatic(
    *,
    seed: int,
    vary: bool = False,
    n_pings: int = 22,
    n_receivers: int | None = None,
    ping_interval_s: float | None = None,
    n_hotspots: int = 5,
    clutter_per_receiver: float = 2.0,
    area_half_width_m: float = 10000.0,
    fom_db: float = 157.0,
    absorption_db_per_km: float = 0.3,
    ts_base_db: float = 5.0,
    ts_specular_db: float = 15.0,
    detection_threshold_db: float = 10.0,
    snr_fluctuation_db: float = 2.0,
    range_sum_sigma_m: float = 30.0,
    bearing_sigma_deg: float = 1.0,
    aspect_sigma_deg: float = 10.0,
    blanking_m: float = 1000.0,
    hotspot_return_probability: float = 0.7,
    hotspot_snr_db: tuple[float, float] = (22.0, 3.0),
) -> MultistaticScenario:
    """Simulate a multistatic active run (see the module docstring for the models).

    Parameters
    ----------
    seed : int
        Random seed; same seed, same scenario.
    vary : bool, optional
        Draw the scenario's assumptions (receivers, detection probabilities, contact errors,
        hotspots, clutter density, target motion, classifier scores) from the seed instead of
        using the fixed ones below (:func:`fusion.simulate.multistatic_varied.simulate_varied`);
        only `n_pings`, `area_half_width_m`, `detection_threshold_db` and `blanking_m` apply
        then. Default False.
    n_pings : int, optional
        Number of pings (default 22, as in the paper's exercise).
    n_receivers : int, optional
        2-4; drawn from the seed when omitted.
    ping_interval_s : float, optional
        s; drawn uniformly in [60, 120] when omitted.
    n_hotspots : int, optional
        Fixed bottom features.
    clutter_per_receiver : float, optional
        Mean number of random clutter detections per receiver and ping.
    area_half_width_m : float, optional
        The area is the square of this half width around the source, m.
    fom_db : float, optional
        Figure of merit ``SL - NL + DI`` of the sonar equation, dB.
    absorption_db_per_km : float, optional
        Absorption ``alpha``, dB/km.
    ts_base_db, ts_specular_db : float, optional
        Target strength off specular and its specular gain, dB.
    detection_threshold_db : float, optional
        Measured SNR needed for a detection, dB.
    snr_fluctuation_db : float, optional
        Standard deviation of the measured SNR about the sonar equation, dB.
    range_sum_sigma_m, bearing_sigma_deg : float, optional
        Errors of the bistatic range sum (m) and of the bearing at the receiver (deg).
    aspect_sigma_deg : float, optional
        Error of the target's reported equivalent aspect angle, deg.
    blanking_m : float, optional
        Echoes with ``rho - |s - r|`` below this are lost in the direct blast, m.
    hotspot_return_probability : float, optional
        Chance that a hotspot echoes on a given ping at a given receiver.
    hotspot_snr_db : (float, float), optional
        Mean and standard deviation of hotspot SNR, dB.

    Returns
    -------
    MultistaticScenario
    """
    if n_pings < 2:
        raise ValueError(f"n_pings must be >= 2, got {n_pings}")
    if vary:
        return simulate_varied(seed, n_pings=n_pings, area_half_width_m=area_half_width_m,
                               detection_threshold_db=detection_threshold_db,
                               blanking_m=blanking_m)
    rng = np.random.default_rng(seed)
    n_rx = int(rng.integers(2, 5)) if n_receivers is None else int(n_receivers)
    if not 1 <= n_rx <= 8:
        raise ValueError(f"n_receivers must lie in 1..8, got {n_rx}")
    interval = float(rng.uniform(60.0, 120.0)) if ping_interval_s is None else float(ping_interval_s)
    if interval <= 0:
        raise ValueError(f"ping_interval_s must be positive, got {interval}")
    speed = rng.uniform(3.0, 8.0) * KNOT
    source = np.zeros(2)
    ang = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n_rx) / n_rx + rng.uniform(-0.3, 0.3, n_rx)
    rad = rng.uniform(4000.0, 7000.0, n_rx)
    receivers = np.column_stack([rad * np.sin(ang), rad * np.cos(ang)])
    hw = area_half_width_m
    hotspots = rng.uniform(-0.8 * hw, 0.8 * hw, (n_hotspots, 2))
    tgt_x, tgt_v = _target_track(rng, n_pings, interval, speed)
    sig_th = np.radians(bearing_sigma_deg)

    rows: dict[str, list] = {k: [] for k in (
        "event", "time", "x", "y", "snr_db", "score", "aspect_deg", "src_x", "src_y", "rcv_x",
        "rcv_y", "origin", "receiver")}

    def measure(p: NDArray[np.float64], rcv: NDArray[np.float64]) -> NDArray[np.float64] | None:
        rho = np.linalg.norm(p - source, axis=-1) + np.linalg.norm(p - rcv, axis=-1)
        if rho - np.linalg.norm(rcv - source) < blanking_m:
            return None
        th = np.arctan2(p[0] - rcv[0], p[1] - rcv[1])
        return bistatic_position(source, rcv, rho + rng.normal(0, range_sum_sigma_m),
                                 th + rng.normal(0, sig_th))

    def add(k: int, xy, snr, score, aspect, j: int, origin: str) -> None:
        for key, val in (("event", k), ("time", k * interval), ("x", xy[0]), ("y", xy[1]),
                         ("snr_db", snr), ("score", score), ("aspect_deg", aspect),
                         ("src_x", source[0]), ("src_y", source[1]), ("rcv_x", receivers[j, 0]),
                         ("rcv_y", receivers[j, 1]), ("origin", origin), ("receiver", j)):
            rows[key].append(val)

    for k in range(n_pings):
        for j, rcv in enumerate(receivers):
            # target: bistatic sonar equation with aspect-dependent target strength
            p, v = tgt_x[k], tgt_v[k]
            us, ur = source - p, rcv - p
            rs, rr = np.linalg.norm(us), np.linalg.norm(ur)
            b = us / rs + ur / rr
            h = v / np.linalg.norm(v)
            aspect = np.degrees(np.arccos(np.clip(h @ b / np.linalg.norm(b), -1, 1)))
            tl = 20 * np.log10(rs) + 20 * np.log10(rr) + absorption_db_per_km * (rs + rr) / 1000
            ts = ts_base_db + ts_specular_db * np.exp(-(((aspect - 90.0) / 12.0) ** 2))
            snr = fom_db - tl + ts + rng.normal(0, snr_fluctuation_db)
            if snr >= detection_threshold_db:
                z = measure(p, rcv)
                if z is not None:
                    add(k, z, snr, rng.beta(5.0, 2.0),
                        float(np.clip(aspect + rng.normal(0, aspect_sigma_deg), 0, 180)), j, "target")
            # hotspots: strong, fixed, on most pings
            for hs in hotspots:
                if rng.random() < hotspot_return_probability:
                    z = measure(hs, rcv)
                    if z is not None:
                        add(k, z, max(rng.normal(*hotspot_snr_db), detection_threshold_db),
                            rng.beta(2.5, 3.5), rng.uniform(0, 180), j, "hotspot")
            # random clutter: Poisson, uniform over the area, SNR just above threshold
            for _ in range(rng.poisson(clutter_per_receiver)):
                add(k, rng.uniform(-hw, hw, 2), detection_threshold_db + rng.exponential(3.0),
                    rng.beta(2.0, 4.0), rng.uniform(0, 180), j, "clutter")

    cols = {k: np.asarray(v) for k, v in rows.items()}
    cols["event"] = cols["event"].astype(np.int64)
    cols["receiver"] = cols["receiver"].astype(np.int64)
    cols["origin"] = cols["origin"].astype(str)
    truth = Table({
        "event": np.arange(n_pings, dtype=np.int64),
        "time": np.arange(n_pings) * interval,
        "x": tgt_x[:, 0], "y": tgt_x[:, 1], "vx": tgt_v[:, 0], "vy": tgt_v[:, 1],
    }, f"multistatic seed {seed}: truth")
    logger.debug("multistatic seed %d: %d detections, %d from the target", seed,
                 cols["event"].size, int(np.sum(cols["origin"] == "target")))
    return MultistaticScenario(
        detections=Table(cols, f"multistatic seed {seed}"),
        truth=truth, source=source, receivers=receivers, hotspots=hotspots,
        ping_interval_s=interval, seed=seed,
    )


def write_scenario(out_dir: Path, *, seed: int, vary: bool = False) -> list[Path]:
    """Write ``detections.csv`` (formats section 3, clue columns included), ``truth.csv``
    (target per ping), ``origins.csv`` (origin of each detection row) and ``truth.json``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).

    Parameters
    ----------
    vary : bool, optional
        A varied scenario (:func:`simulate_multistatic` with ``vary=True``); its drawn
        parameters go to ``truth.json`` under ``parameters``.
    """
    out = Path(out_dir)
    sc = simulate_multistatic(seed=seed, vary=vary)
    d = sc.detections.columns
    det_cols = ("event", "time", "x", "y", "snr_db", "score", "aspect_deg", "src_x", "src_y",
                "rcv_x", "rcv_y")
    paths = [
        write_table(out / "detections.csv", {k: d[k] for k in det_cols}),
        write_table(out / "truth.csv", sc.truth.columns),
        write_table(out / "origins.csv", {"row": np.arange(len(sc.detections)),
                                          "origin": d["origin"], "receiver": d["receiver"]}),
        write_json(out / "truth.json", {
            "kind": "multistatic", "seed": seed, "ping_interval_s": sc.ping_interval_s,
            "source": sc.source, "receivers": sc.receivers, "hotspots": sc.hotspots,
            **({"vary": True, "parameters": sc.parameters} if vary else {}),
        }),
    ]
    return paths
