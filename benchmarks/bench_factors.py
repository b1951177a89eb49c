"""Benchmark of the fast factor forms against the scalar-factor path they replace.

Prints one JSON line of measured metrics (human lines on stderr)::

    python benchmarks/bench_factors.py [--seed S] [--repeats R] [--scans N] [--bearings M]
                                       [--weighted W] [--tracks T] [--isam-scans K]
                                       [--isam-long-scans L] [--skip-old]

Parts (targets in brackets):

* ``smoother_ms``: :class:`BearingSmoother` on ``--scans`` scans (<= 100 ms for 1,000): built-in
  linear factors, one sparse solve, marginals. The old path is the same graph of scalar
  ``CustomFactor`` s (``bearing_factor``, ``constant_velocity_factor``) solved by
  Levenberg-Marquardt from the same start.
* ``tma_ms``: :class:`BearingsOnlyTMA` on ``--bearings`` bearings (<= 20 ms for 2,000): one
  vector bearing factor. The old path is the same single-state graph with one
  ``target_bearing_factor`` per bearing, from the same start and with the same optimiser.
* ``weighted_first_linearize_ms``: first linearisation of a graph of ``--weighted``
  association-weighted bearing factors (<= 100 ms for 2,000), and a later one; their answer is
  checked against the same factors with the weight folded into the noise.
* ``isam2_ms_per_scan``: one :class:`OnlineBearingSmootherSet` step (one iSAM2 update) for
  ``--tracks`` tracks (<= 5 ms for 100), median over the first ``--isam-scans`` scans, and the
  median around ``--isam-long-scans`` scans (an iSAM2 update grows with the chains it holds);
  ``isam2_per_track_ms_per_scan``: one :class:`OnlineBearingSmoother` (one iSAM2) per track.
  The old path is iSAM2 over the scalar factors for a few of the tracks.
* ``*_cpu_ms``: process CPU time of the same calls (the cores are shared; wall time then
  includes waiting for them).
* ``max_answer_diff``: the largest difference of answers against the old path (<= 1e-9): rad and
  rad/s for the smoothers, relative for the TMA state, whitened units for the weighted factors.

There is nothing to tune: the seed (default 2026) only draws the data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import gtsam
import numpy as np

from factors.bearing import bearing_factor, linear_bearing_factors
from factors.motion import constant_velocity_factor, wna_covariance
from factors.target import target_bearing_factor
from factors.weighted import weighted_factor
from fusion.passive.smoothing import (
    BearingSmoother,
    OnlineBearingSmoother,
    OnlineBearingSmootherSet,
    TrackPrior,
)
from fusion.passive.tma import BearingsOnlyTMA, OwnshipTrack
from fusion.simulate.tma import simulate_tma

SIG, Q = 0.01, 1e-8


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _lm(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, *, rel: float, abs_: float,
        iters: int = 100) -> gtsam.Values:
    p = gtsam.LevenbergMarquardtParams()
    p.setMaxIterations(iters)
    p.setRelativeErrorTol(rel)
    p.setAbsoluteErrorTol(abs_)
    return gtsam.LevenbergMarquardtOptimizer(graph, values, p).optimize()


def _best_of(fn, repeats: int) -> tuple[float, float, float, object]:
    """Median and minimum wall time and median process CPU time (ms) of `repeats` calls, and
    the last result (CPU time is what the code costs when other jobs share the cores)."""
    times, cpu, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        times.append(1e3 * (time.perf_counter() - t0))
        cpu.append(1e3 * (time.process_time() - c0))
    return float(np.median(times)), float(np.min(times)), float(np.median(cpu)), out


def bench_smoother(rng: np.random.Generator, n: int, repeats: int, old: bool) -> dict:
    t = np.cumsum(rng.uniform(2.0, 8.0, n))
    s = t - t[0]
    theta = np.pi - 0.3 + 0.001 * s + 1e-6 * s**2  # crosses +-180 deg
    z = np.mod(theta + rng.normal(0.0, SIG, n) + np.pi, 2 * np.pi) - np.pi
    prior = TrackPrior(bearing=z[0], rate=0.0, sigma_bearing=0.05, sigma_rate=0.01)
    sm = BearingSmoother(sigma_bearing=SIG, q=Q)
    med, best, cpu, res = _best_of(lambda: sm.smooth(t, z, prior=prior), repeats)
    out = {"smoother_scans": n, "smoother_ms": med, "smoother_ms_min": best,
           "smoother_cpu_ms": cpu}
    if not old:
        return out
    # the scalar-factor path: same prior, same start (the unwrapped measurements)
    t0, c0 = time.perf_counter(), time.process_time()
    g = gtsam.NonlinearFactorGraph()
    g.add(gtsam.PriorFactorVector(0, prior.mean, gtsam.noiseModel.Gaussian.Covariance(
        prior.covariance)))
    for k, dt in enumerate(np.diff(t)):
        noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, Q, 1))
        g.add(constant_velocity_factor(noise, k, k + 1, float(dt)))
    bn = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    for k in range(n):
        g.add(bearing_factor(bn, k, float(z[k])))
    init = gtsam.Values()
    for k, zk in enumerate(np.unwrap(z)):
        init.insert(k, np.array([zk, 0.0]))
    sol = _lm(g, init, rel=1e-15, abs_=1e-20)
    marg = gtsam.Marginals(g, sol)
    x = np.array([sol.atVector(k) for k in range(n)])
    sig = np.sqrt(np.array([marg.marginalCovariance(k).diagonal() for k in range(n)]))
    out["old_smoother_ms"] = 1e3 * (time.perf_counter() - t0)
    out["old_smoother_cpu_ms"] = 1e3 * (time.process_time() - c0)
    d_b = np.abs(np.angle(np.exp(1j * (res.bearing - x[:, 0]))))
    out["smoother_diff_bearing_rad"] = float(d_b.max())
    out["smoother_diff_rate_rad_s"] = float(np.abs(res.rate - x[:, 1]).max())
    out["smoother_diff_sigma_rad"] = float(np.abs(res.sigma_bearing - sig[:, 0]).max())
    return out


def bench_tma(seed: int, m: int, repeats: int, old: bool) -> dict:
    sc = simulate_tma(seed=seed, duration_s=float(m), period_s=1.0)
    track = OwnshipTrack(sc.ownship_times, sc.ownship_xy)
    tma = BearingsOnlyTMA(bearing_sigma_deg=sc.bearing_sigma_deg)
    med, best, cpu, res = _best_of(lambda: tma.estimate(sc.times, sc.bearings, track), repeats)
    out = {"tma_bearings": int(sc.times.size), "tma_ms": med, "tma_ms_min": best,
           "tma_cpu_ms": cpu,
           "tma_final_range_err_pct": float(100 * abs(res.range[-1] / np.hypot(
               *(sc.truth[-1, :2] - res.ownship_xy[-1])) - 1.0))}
    if not old:
        return out
    # the scalar-factor path: one target_bearing_factor per bearing, same start and optimiser
    t, z, own = sc.times, sc.bearings, res.ownship_xy
    s0 = tma.initial_state(t, z, own)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, np.radians(sc.bearing_sigma_deg))
    prior = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e5, 1e5, 100.0, 100.0]))
    key = gtsam.symbol("s", 0)
    t0, c0 = time.perf_counter(), time.process_time()
    g = gtsam.NonlinearFactorGraph()
    g.add(gtsam.PriorFactorVector(key, s0, prior))
    for k in range(t.size):
        g.add(target_bearing_factor(noise, key, own[k], float(z[k]), dt=float(t[k] - t[0])))
    init = gtsam.Values()
    init.insert(key, s0)
    sol = _lm(g, init, rel=1e-10, abs_=1e-12).atVector(key)
    out["old_tma_solve_ms"] = 1e3 * (time.perf_counter() - t0)
    out["old_tma_solve_cpu_ms"] = 1e3 * (time.process_time() - c0)
    # the new graph with the same optimiser settings, for an exact comparison of the solves
    new_graph, new_init, keys = tma._build("single", t, z, own, s0)
    new = _lm(new_graph, new_init, rel=1e-10, abs_=1e-12).atVector(keys[0])
    out["tma_diff_state_rel"] = float(np.max(np.abs(new - sol)) / np.max(np.abs(sol)))
    return out


def bench_weighted(rng: np.random.Generator, n: int) -> dict:
    x = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.normal(0.0, 0.01, n)])
    z = x[:, 0] + rng.normal(0.0, SIG, n)
    w = rng.uniform(0.05, 1.0, n)
    values = gtsam.Values()
    for k in range(n):
        values.insert(k, x[k])
    noise = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    inner = linear_bearing_factors(noise, range(n), z, estimates=x)
    graph = gtsam.NonlinearFactorGraph()
    for k, f in enumerate(inner):
        graph.add(weighted_factor(f, w, k))
    t0, c0 = time.perf_counter(), time.process_time()
    first = graph.linearize(values)
    t1, c1 = time.perf_counter(), time.process_time()
    graph.linearize(values)
    t2 = time.perf_counter()
    # the same factors with the weight folded into the noise: precision w / sigma^2
    folded = gtsam.NonlinearFactorGraph()
    for k in range(n):
        f = linear_bearing_factors(gtsam.noiseModel.Isotropic.Sigma(1, SIG / np.sqrt(w[k])), [k],
                                   [z[k]], estimates=x[k: k + 1])[0]
        folded.add(f)
    order = gtsam.Ordering(list(range(n)))
    a1, b1 = first.jacobian(order)
    a2, b2 = folded.linearize(values).jacobian(order)
    return {"weighted_factors": n, "weighted_first_linearize_ms": 1e3 * (t1 - t0),
            "weighted_first_linearize_cpu_ms": 1e3 * (c1 - c0),
            "weighted_later_linearize_ms": 1e3 * (t2 - t1),
            "weighted_diff": float(max(np.abs(a1 - a2).max(), np.abs(b1 - b2).max()))}


def _old_online(prior: TrackPrior, times: np.ndarray, z: np.ndarray) -> np.ndarray:
    """iSAM2 over the scalar factors, one scan at a time: the filtered states."""
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(1e-3)
    params.relinearizeSkip = 1
    isam = gtsam.ISAM2(params)
    g = gtsam.NonlinearFactorGraph()
    g.add(gtsam.PriorFactorVector(0, prior.mean, gtsam.noiseModel.Gaussian.Covariance(
        prior.covariance)))
    v = gtsam.Values()
    v.insert(0, prior.mean)
    isam.update(g, v)
    bn = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    last, out = prior.mean, []
    for k in range(1, times.size):
        dt = float(times[k] - times[k - 1])
        g = gtsam.NonlinearFactorGraph()
        g.add(constant_velocity_factor(gtsam.noiseModel.Gaussian.Covariance(
            wna_covariance(dt, Q, 1)), k - 1, k, dt))
        g.add(bearing_factor(bn, k, float(z[k])))
        v = gtsam.Values()
        v.insert(k, np.array([last[0] + dt * last[1], last[1]]))
        isam.update(g, v)
        last = isam.calculateEstimateVector(k)
        out.append(last.copy())
    return np.array(out)


def bench_isam(rng: np.random.Generator, n_tracks: int, n_scans: int, long_scans: int,
               old: bool) -> dict:
    b0 = rng.uniform(-np.pi, np.pi, n_tracks)
    r0 = rng.normal(0.0, 0.002, n_tracks)
    priors = [TrackPrior(bearing=b, rate=0.0, sigma_bearing=0.05, sigma_rate=0.01) for b in b0]
    n_all = max(n_scans, long_scans)
    times = 10.0 * np.arange(n_all + 1)
    z = b0[None, :] + r0[None, :] * times[:, None] + rng.normal(0.0, SIG, (n_all + 1, n_tracks))
    z = np.mod(z + np.pi, 2 * np.pi) - np.pi
    # all tracks in one iSAM2: one update per scan
    bank = OnlineBearingSmootherSet(priors=priors, t0=0.0, sigma_bearing=SIG, q=Q)
    per, cpu, est = [], [], np.zeros((n_all, n_tracks, 2))
    for k in range(1, n_all + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        est[k - 1] = bank.step(times[k], [[zz] for zz in z[k]])
        per.append(1e3 * (time.perf_counter() - t0))
        cpu.append(1e3 * (time.process_time() - c0))
    out = {"isam2_tracks": n_tracks, "isam2_scans": n_scans,
           "isam2_ms_per_scan": float(np.median(per[:n_scans])),
           "isam2_ms_per_scan_min": float(np.min(per[:n_scans])),
           "isam2_cpu_ms_per_scan": float(np.median(cpu[:n_scans])),
           f"isam2_ms_per_scan_at_{long_scans}_scans": float(np.median(per[long_scans - 10:
                                                                           long_scans]))}
    # one iSAM2 per track (OnlineBearingSmoother), same scans
    sms = [OnlineBearingSmoother(prior=p, t0=0.0, sigma_bearing=SIG, q=Q) for p in priors]
    per_track, cpu_track = [], []
    for k in range(1, n_scans + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        for j, sm in enumerate(sms):
            sm.step(times[k], [z[k, j]])
        per_track.append(1e3 * (time.perf_counter() - t0))
        cpu_track.append(1e3 * (time.process_time() - c0))
    out["isam2_per_track_ms_per_scan"] = float(np.median(per_track))
    out["isam2_per_track_cpu_ms_per_scan"] = float(np.median(cpu_track))
    if old:
        diffs, t_old = [], 0.0
        for j in range(min(5, n_tracks)):
            c0 = time.process_time()
            ref = _old_online(priors[j], times[: n_scans + 1], z[: n_scans + 1, j])
            t_old += time.process_time() - c0
            d = est[:n_scans, j] - ref
            d[:, 0] = np.angle(np.exp(1j * d[:, 0]))
            diffs.append(np.abs(d).max())
        out["old_isam2_cpu_ms_per_scan"] = 1e3 * t_old / min(5, n_tracks) * n_tracks / n_scans
        out["isam2_diff_state"] = float(max(diffs))
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print one JSON line."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2026, help="report seed (draws the data)")
    ap.add_argument("--repeats", type=int, default=7, help="timed repeats of each part")
    ap.add_argument("--scans", type=int, default=1000, help="scans of the batch smoother")
    ap.add_argument("--bearings", type=int, default=2000, help="bearings of the TMA")
    ap.add_argument("--weighted", type=int, default=2000, help="association-weighted factors")
    ap.add_argument("--tracks", type=int, default=100, help="tracks of the iSAM2 timing")
    ap.add_argument("--isam-scans", type=int, default=20, help="scans of the iSAM2 timing")
    ap.add_argument("--isam-long-scans", type=int, default=200,
                    help="scan count at which the iSAM2 cost is also reported (it grows)")
    ap.add_argument("--skip-old", action="store_true", help="skip the old scalar-factor path")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    old = not a.skip_old
    out: dict = {"benchmark": "factors", "seed": a.seed}
    for name, fn in (
        ("smoother", lambda: bench_smoother(rng, a.scans, a.repeats, old)),
        ("tma", lambda: bench_tma(a.seed, a.bearings, a.repeats, old)),
        ("weighted", lambda: bench_weighted(rng, a.weighted)),
        ("isam2", lambda: bench_isam(rng, a.tracks, a.isam_scans, a.isam_long_scans, old)),
    ):
        t0 = time.perf_counter()
        part = fn()
        out.update(part)
        _log(f"{name}: {part} ({time.perf_counter() - t0:.1f} s)")
    diffs = [out[k] for k in ("smoother_diff_bearing_rad", "smoother_diff_rate_rad_s",
                              "smoother_diff_sigma_rad", "tma_diff_state_rel", "weighted_diff",
                              "isam2_diff_state") if k in out]
    out["max_answer_diff"] = float(max(diffs)) if diffs else None
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
