"""Benchmark of bearing-rate smoothing: RTS equality, outliers, crossings, iSAM2, real data.

Prints one JSON line of measured metrics (human lines on stderr)::

    python benchmarks/bench_smoothing.py [--seeds N] [--min-crossings M] [--tracks T]
    python benchmarks/bench_smoothing.py --association [--report]   # the ablation alone
    python benchmarks/bench_smoothing.py --association --seeds-from 9700 --seed-count 30 \
        [--variants weighted no-relink short-gaps no-curvature no-short-links ends starts nearest nn jpda] \
        [--short-link-accel-psd-deg2-per-s3 5e-4] \
        [--slow-deg-per-min 6]

The association ablation (``--association``, issue 18) runs on :data:`TUNING_SEEDS` (the seeds
the association was developed on), with ``--report`` once on :data:`REPORT_SEEDS`, or on a
fresh range (``--seeds-from``). Variants: weighted (the default smoother), ``no-relink``
(weighted, no second link assignment: ``fusion smooth --relink-gate 30``), ``short-gaps``
(weighted, links across a crossing no longer than others: ``--crossing-gap-scans 40``),
``no-curvature`` (weighted, constant-rate links: ``--no-link-curvature``), ``ends`` (weighted,
tracks extended over their ambiguous ends: ``fusion smooth --end-extension``), nearest
assignment, the nearest-neighbour tracker alone, Stone Soup's JPDA. Every crossing not kept
is classified (``crossing_failure_causes``: one stderr line each, counts in the JSON).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from _realdata import AUTOFERRY as REALDATA

from fusion.metrics.crossings import (
    CROSSING_OUTCOMES,
    FAILURE_CAUSES,
    crossing_bearing_errors,
    crossing_failure_causes,
    crossing_outcomes,
    crossing_window_identity,
)
from fusion.passive.smoothing import (
    BearingSmoother,
    MultiTrackSmoother,
    NearestNeighbourTracker,
    OnlineBearingSmoother,
    TrackPrior,
    rts_reference,
)
from fusion.passive.smoothing.settings import fit_smooth_settings
from fusion.pipelines.bearing_smoothing import LINK_PATH_ALPHA, SHORT_LINK_Q_DEG2_PER_S3
from fusion.simulate.bearings import simulate_bearings

#: Seeds of the association ablation used while developing it (issue 18) ...
TUNING_SEEDS = tuple(range(9200, 9220))
#: ... and the seeds of its one report run, drawn after the last design change.
REPORT_SEEDS = tuple(range(9418, 9448))


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _track(rng, n, sig):
    t = np.cumsum(rng.uniform(2.0, 8.0, n))
    s = t - t[0]
    theta = 0.2 + 0.001 * s + 1e-6 * s**2
    return t, theta, theta + rng.normal(0, sig, n)


def bench_rts(seeds: int, sig=0.01, q=1e-8, n=100) -> dict:
    """Batch graph against filterpy's Kalman filter + RTS smoother on the same tracks: the
    largest difference, and the time of each (states and sigmas), best of 3 per track."""
    worst, t_graph, t_rts = 0.0, 0.0, 0.0
    for s in range(seeds):
        t, _, z = _track(np.random.default_rng(s), n, sig)
        prior = TrackPrior(bearing=z[0], rate=0.0, sigma_bearing=0.05, sigma_rate=0.01)
        sm = BearingSmoother(sigma_bearing=sig, q=q)
        dts = []
        for _ in range(3):
            t0 = time.perf_counter()
            r = sm.smooth(t, z, prior=prior)
            dts.append(time.perf_counter() - t0)
        t_graph += min(dts)
        dts = []
        for _ in range(3):
            t0 = time.perf_counter()
            ref = rts_reference(t, z, prior, sigma_bearing=sig, q=q)[0]
            dts.append(time.perf_counter() - t0)
        t_rts += min(dts)
        worst = max(worst, float(np.max(np.abs(r.bearing - ref[:, 0]))))
    return {"rts_max_abs_diff_rad": worst, "rts_graph_ms_per_track": 1e3 * t_graph / seeds,
            "rts_filterpy_ms_per_track": 1e3 * t_rts / seeds,
            "rts_time_ratio_graph_to_filterpy": t_graph / t_rts}


def bench_outliers(seeds: int, sig=0.01, q=1e-8, frac=0.10) -> dict:
    e = {"rts": [], "huber": [], "cauchy": []}
    for s in range(seeds):
        rng = np.random.default_rng(1000 + s)
        t, theta, z = _track(rng, 100, sig)
        out = rng.random(t.size) < frac
        z[out] = rng.uniform(-np.pi, np.pi, out.sum())  # false bearings, uniform
        prior = TrackPrior(bearing=theta[0], rate=0.0, sigma_bearing=0.05, sigma_rate=0.01)
        xs = rts_reference(t, z, prior, sigma_bearing=sig, q=q)[0]
        e["rts"].append(np.mean(np.angle(np.exp(1j * (xs[:, 0] - theta))) ** 2))
        for loss in ("huber", "cauchy"):
            r = BearingSmoother(sigma_bearing=sig, q=q, robust=loss).smooth(t, z)
            e[loss].append(np.mean(np.angle(np.exp(1j * (r.bearing - theta))) ** 2))
    rm = {k: float(np.sqrt(np.mean(v))) for k, v in e.items()}
    return {"outlier_rmse_rts_rad": rm["rts"], "outlier_rmse_huber_rad": rm["huber"],
            "outlier_rmse_cauchy_rad": rm["cauchy"],
            "outlier_ratio_cauchy_to_rts": rm["cauchy"] / rm["rts"],
            "outlier_ratio_huber_to_rts": rm["huber"] / rm["rts"]}


def bench_crossings(min_crossings: int, q=1e-9) -> dict:
    """Identities through true crossings from unlabeled detections (seeds 500, 501, ...).

    Every crossing is scored by :func:`crossing_outcomes` (kept, swap, lost, unscored) with a
    15-scan guard and 20-scan windows; scenarios are added until `min_crossings` are scored.
    """
    n = 0
    seed, secs = 0, 0.0
    tally = {"em": dict.fromkeys(CROSSING_OUTCOMES, 0), "nn": dict.fromkeys(CROSSING_OUTCOMES, 0)}
    while n < min_crossings:
        sc = simulate_bearings(seed=500 + seed, n_tracks=6, n_crossing_pairs=3,
                               n_near_miss_pairs=0, clutter_rate=0.2, p_detect=0.9)
        seed += 1
        t, z, sig = sc.time, np.radians(sc.bearing_deg), np.radians(sc.noise_deg)
        cr = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
        nn = NearestNeighbourTracker(sigma_bearing=sig, q=q).run(t, z)
        t0 = time.perf_counter()
        em = MultiTrackSmoother(sigma_bearing=sig, q=q,
                                clutter_density=0.2 / (2 * np.pi)).run(t, z)
        secs += time.perf_counter() - t0
        kw = {"guard_s": 15 * sc.sample_period_s, "window_s": 20 * sc.sample_period_s}
        for name, lab in (("em", em.labels), ("nn", nn.labels)):
            for o in crossing_outcomes(sc.track_id, lab, t, cr, **kw):
                tally[name][str(o)] += 1
        n = tally["em"]["kept"] + tally["em"]["swap"] + tally["em"]["lost"]
        _log(f"scored crossings {n}: em {tally['em']}, nn {tally['nn']}")
    if n == 0:
        return {}
    out = {"crossings_scored": n, "crossings_unscored": tally["em"]["unscored"],
           "scenarios": seed, "em_seconds_per_scenario": secs / seed}
    for name in ("em", "nn"):
        for o in ("swap", "lost", "kept"):
            out[f"{o}_rate_{name}"] = tally[name][o] / n
    return out


def _association_scenario(seed: int):
    """Unlabelled bearings: 2-6 tracks, P_D 0.7-0.9, 0.5-2 clutter bearings per scan."""
    rng = np.random.default_rng(seed)
    n_tracks = int(rng.integers(2, 7))
    p_d = float(rng.uniform(0.7, 0.9))
    clutter = float(rng.uniform(0.5, 2.0))
    sc = simulate_bearings(seed=seed, n_tracks=n_tracks, n_crossing_pairs=n_tracks // 2,
                           n_wrap_crossings=1, n_near_miss_pairs=0, clutter_rate=clutter,
                           p_detect=p_d, noise_deg=float(rng.uniform(0.3, 1.0)))
    return sc, {"tracks": n_tracks, "p_detect": p_d, "clutter_per_scan": clutter}


def _smoother_from_data(t, z, association: str, st=None,
                        extend_ends: bool = False, relink_gate: float = 100.0,
                        crossing_gap_scans: int | None = 60, link_curvature: bool = True,
                        extend_starts: bool = False,
                        short_link_q_deg2_per_s3: float = SHORT_LINK_Q_DEG2_PER_S3,
                        link_path_alpha: float = LINK_PATH_ALPHA) -> tuple[MultiTrackSmoother, object]:
    """The multi-track smoother as ``fusion smooth`` builds it: every setting fitted to the
    unlabelled rows (nothing from the truth; `st` those settings if already fitted); the
    clutter density of the association counted by the smoother itself from the detections
    its tracks leave."""
    st = fit_smooth_settings(np.full(t.size, -1), t, z) if st is None else st
    mts = MultiTrackSmoother(
        sigma_bearing=np.radians(st.sigma_bearing_deg),
        q=st.q_deg2_per_s3 * np.radians(1.0) ** 2, clutter_density=None,
        p_detect=st.p_detect, min_length=st.min_length, association=association,
        init_sigma_rate=np.radians(st.init_sigma_rate_deg_per_s), max_misses=st.max_misses,
        max_gap_scans=st.max_gap_scans, extend_ends=extend_ends, relink_gate=relink_gate,
        crossing_gap_scans=crossing_gap_scans, link_curvature=link_curvature,
        extend_starts=extend_starts, short_link_q=short_link_q_deg2_per_s3 * np.radians(1.0) ** 2,
        link_path_alpha=link_path_alpha)
    return mts, st


#: Variants of the association ablation.
VARIANTS = ("weighted", "no-relink", "short-gaps", "no-curvature", "no-short-links", "ends",
            "starts", "no-path-test", "nearest", "nn", "jpda")


def bench_association(seeds, within_s: float = 60.0, names=VARIANTS,
                      slow_deg_per_min: float = 6.0,
                      short_link_q_deg2_per_s3: float = SHORT_LINK_Q_DEG2_PER_S3,
                      link_path_alpha: float = LINK_PATH_ALPHA) -> dict:
    """Weighted against nearest association, the plain nearest-neighbour tracker and Stone
    Soup's JPDA tracker (:mod:`_jpda`) on the same unlabelled bearings (settings fitted once
    per scenario, outside the timings): outcomes around each crossing (15-scan guard, 20-scan
    windows),
    identity per detection inside the guard, bearing RMS within `within_s` of each crossing
    (per crossing target, the track that followed it before), divided by the noise; the
    cause of every crossing not kept (:func:`~fusion.metrics.crossings.
    crossing_failure_causes`, one stderr line each)."""
    if "jpda" in names:
        from _jpda import run_jpda  # Stone Soup, only for this part

    tally = {n: dict.fromkeys(CROSSING_OUTCOMES, 0) for n in names}
    inside = {n: np.zeros(2, np.int64) for n in names}
    err = {n: [] for n in names}
    secs = {n: 0.0 for n in names}
    causes = {n: dict.fromkeys(FAILURE_CAUSES, 0) for n in names}
    noise_sq = []
    for seed in seeds:
        sc, info = _association_scenario(seed)
        t, z = sc.time, np.radians(sc.bearing_deg)
        cr = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
        kw = {"guard_s": 15 * sc.sample_period_s, "window_s": 20 * sc.sample_period_s}
        truth = {int(k): np.radians(sc.truth_bearing_deg[i]) for i, k in enumerate(sc.track_ids)}
        noise = np.radians(np.atleast_1d(sc.noise_deg))
        st = fit_smooth_settings(np.full(t.size, -1), t, z)
        lam_counted = st.clutter_density
        for name in names:
            t0 = time.perf_counter()
            if name == "jpda":  # the same fitted settings and counted clutter density
                lab, tracks = run_jpda(
                    t, z, sigma=np.radians(st.sigma_bearing_deg),
                    q=st.q_deg2_per_s3 * np.radians(1.0) ** 2, p_detect=st.p_detect,
                    clutter_density=lam_counted, max_misses=st.max_misses,
                    init_sigma_rate=np.radians(st.init_sigma_rate_deg_per_s))
            elif name == "nn":
                mts, _ = _smoother_from_data(t, z, "nearest", st)
                res = mts.tracker.run(t, z)
                lab = res.labels
                tracks = {m: (res.scan_times[res.first_scan[m]: res.last_scan[m] + 1],
                              res.states[m][:, 0]) for m in range(res.n_tracks)}
            else:  # "ends": weighted, tracks extended beyond their end segments;
                # "no-relink": weighted, no second link assignment (relink_gate = link_gate);
                # "short-gaps": weighted, links across crossings no longer than other links;
                # "no-curvature": weighted, constant-rate links; "no-path-test": no link-path
                # test; "no-short-links": no short-chain
                # links; "starts": tracks extended before their first segment
                mts, _ = _smoother_from_data(
                    t, z, "nearest" if name == "nearest" else "weighted", st,
                    extend_ends=name == "ends", relink_gate=30.0 if name == "no-relink" else 100.0,
                    crossing_gap_scans=None if name == "short-gaps" else 60,
                    link_curvature=name != "no-curvature", extend_starts=name == "starts",
                    short_link_q_deg2_per_s3=0.0 if name == "no-short-links"
                    else short_link_q_deg2_per_s3,
                    link_path_alpha=0.0 if name == "no-path-test" else link_path_alpha)
                res = mts.run(t, z)
                if name == "weighted":
                    lam_counted = mts.used_clutter_density
                lab = res.labels
                tracks = {tr.track_id: (tr.times, tr.bearing) for tr in res.tracks}
            secs[name] += time.perf_counter() - t0
            for o in crossing_outcomes(sc.track_id, lab, t, cr, **kw):
                tally[name][str(o)] += 1
            rd = sc.crossing_rate_diff_deg_per_min
            for (a, b, tc), c, r in zip(cr, crossing_failure_causes(
                    sc.track_id, lab, t, cr, rd, slow_deg_per_min=slow_deg_per_min, **kw),
                    rd, strict=True):
                if c:
                    causes[name][c] += 1
                    _log(f"  {name} seed {seed} crossing {a}-{b} at {tc:.0f} s, "
                         f"rate diff {r:+.1f} deg/min: {c}")
            inside[name] += crossing_window_identity(sc.track_id, lab, t, cr, **kw).sum(axis=0)
            e = crossing_bearing_errors(sc.track_id, lab, t, cr, tracks, sc.truth_time, truth,
                                        within_s=within_s, **kw)
            err[name].append(e)
        noise_sq.append(float(np.mean(noise**2)))
        _log(f"seed {seed} {info}: " + "; ".join(
            f"{n} {tally[n]['kept']}/{tally[n]['swap']}/{tally[n]['lost']} inside "
            f"{inside[n][1]}/{inside[n][0]}" for n in names))
    out = {"association_seeds": [int(seeds[0]), int(seeds[-1])],
           "noise_rms_deg": float(np.degrees(np.sqrt(np.mean(noise_sq))))}
    for n in names:
        scored = tally[n]["kept"] + tally[n]["swap"] + tally[n]["lost"]
        e = np.concatenate(err[n])
        cov = np.isfinite(e)
        out[n] = {"scored": scored, "unscored": tally[n]["unscored"],
                  "kept": tally[n]["kept"] / max(scored, 1), "swap": tally[n]["swap"] / max(scored, 1),
                  "lost": tally[n]["lost"] / max(scored, 1),
                  "inside_correct": float(inside[n][1] / max(inside[n][0], 1)),
                  "rms_60s_deg": float(np.degrees(np.sqrt(np.mean(e[cov] ** 2)))) if cov.any()
                  else float("nan"),
                  "rms_60s_covered": float(cov.mean()) if e.size else 0.0,
                  "seconds_per_scenario": secs[n] / len(seeds),
                  "failure_causes": causes[n]}
    return out


def bench_isam(n_tracks: int, n_scans=20, sig=0.01, q=1e-8) -> dict:
    rng = np.random.default_rng(3)
    b0 = rng.uniform(-np.pi, np.pi, n_tracks)
    r0 = rng.normal(0, 0.002, n_tracks)
    sms = [OnlineBearingSmoother(prior=TrackPrior(bearing=b, rate=0.0, sigma_bearing=0.05,
                                                  sigma_rate=0.01), t0=0.0, sigma_bearing=sig, q=q)
           for b in b0]
    per = []
    for k in range(1, n_scans + 1):
        z = b0 + r0 * k * 10.0 + rng.normal(0, sig, n_tracks)
        t0 = time.perf_counter()
        for sm, zz in zip(sms, z, strict=True):
            sm.step(k * 10.0, [zz])
        per.append(time.perf_counter() - t0)
    return {"isam2_ms_per_scan": 1e3 * float(np.median(per)), "isam2_tracks": n_tracks}


def bench_real(scenario: str = "scenario2") -> dict:
    from fusion.datasets.autoferry import Sensor, load_autoferry

    rec = load_autoferry(REALDATA / scenario)
    b = rec.bearings(sensors=(Sensor.EO,))
    truth = rec.true_bearings()
    t, z = b["time"], np.radians(b["bearing_deg"])
    order = np.argsort(t, kind="stable")
    t, z = t[order], z[order]
    t0 = time.perf_counter()
    res = MultiTrackSmoother(sigma_bearing=np.radians(1.0), q=1e-4, clutter_density=0.5,
                             p_detect=0.8, init_sigma_rate=0.05, min_length=20).run(t, z)
    secs = time.perf_counter() - t0
    out = {"real_scenario": scenario, "real_tracks": len(res.tracks), "real_seconds": secs}
    for tid in np.unique(truth["track_id"]):
        sel = truth["track_id"] == tid
        tt, tb = truth["time"][sel], np.radians(truth["bearing_deg"][sel])
        best = None
        for tr in res.tracks:  # the output track closest to this target
            m = (tt >= tr.times[0]) & (tt <= tr.times[-1])
            if m.sum() < 20:
                continue
            est = np.angle(np.interp(tt[m], tr.times, np.cos(tr.bearing))
                           + 1j * np.interp(tt[m], tr.times, np.sin(tr.bearing)))
            err = np.angle(np.exp(1j * (est - tb[m])))
            rmse = float(np.degrees(np.sqrt(np.mean(err**2))))
            cover = float(m.sum() / sel.sum())
            if best is None or rmse < best[0]:
                best = (rmse, cover, tr.track_id)
        if best is not None:
            out[f"real_target{int(tid)}_rmse_deg"] = best[0]
            out[f"real_target{int(tid)}_coverage"] = best[1]
    raw = []  # raw bearing error: every EO bearing vs the nearest true bearing at its time
    for tid in np.unique(truth["track_id"]):
        sel = truth["track_id"] == tid
        raw.append(np.interp(t, truth["time"][sel], np.unwrap(np.radians(truth["bearing_deg"][sel]))))
    d = np.min(np.abs(np.angle(np.exp(1j * (z[None] - np.array(raw))))), axis=0)
    out["real_raw_median_abs_err_deg"] = float(np.degrees(np.median(d)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="seeds of the single-track parts")
    ap.add_argument("--min-crossings", type=int, default=100, help="crossings to score")
    ap.add_argument("--tracks", type=int, default=100, help="tracks of the iSAM2 timing")
    ap.add_argument("--skip-real", action="store_true", help="skip the real-data part")
    ap.add_argument("--association", action="store_true",
                    help="run the association ablation alone (weighted / nearest / tracker)")
    ap.add_argument("--report", action="store_true",
                    help="the ablation on its report seeds instead of its tuning seeds")
    ap.add_argument("--seed-count", type=int, default=None,
                    help="first N seeds of the ablation's set (default all)")
    ap.add_argument("--seeds-from", type=int, default=None,
                    help="the ablation on --seed-count seeds from this one instead of a named "
                         "set (a fresh report set)")
    ap.add_argument("--slow-deg-per-min", type=float, default=6.0,
                    help="a swapped crossing whose bearing rates differ by less than this is "
                         "counted as a slow-crossing swap")
    ap.add_argument("--short-link-accel-psd-deg2-per-s3", type=float,
                    default=SHORT_LINK_Q_DEG2_PER_S3,
                    help="acceleration PSD of the short-chain links of the smoother's variants, "
                         f"deg^2/s^3 (default {SHORT_LINK_Q_DEG2_PER_S3:g}, as fusion smooth)")
    ap.add_argument("--link-path-alpha", type=float, default=LINK_PATH_ALPHA,
                    help="significance level of the link-path test of the smoother's variants "
                         f"(default {LINK_PATH_ALPHA:g}, as fusion smooth; 0: off)")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS),
                    help="variants of the ablation (default all)")
    a = ap.parse_args(argv)
    if a.association:
        seeds = REPORT_SEEDS if a.report else TUNING_SEEDS
        seeds = seeds[: a.seed_count] if a.seed_count else seeds
        label = "report" if a.report else "tuning"
        if a.seeds_from is not None:
            seeds = tuple(range(a.seeds_from, a.seeds_from + (a.seed_count or 30)))
            label = f"from {a.seeds_from}"
        names = tuple(v for v in VARIANTS if v in a.variants)  # jpda after weighted
        out = {"seed_set": label, **bench_association(seeds, names=names,
                                                           slow_deg_per_min=a.slow_deg_per_min,
                                                           short_link_q_deg2_per_s3=(
                                                               a.short_link_accel_psd_deg2_per_s3),
                                                           link_path_alpha=a.link_path_alpha)}
        print(json.dumps(out))
        return 0
    out = {}
    for name, fn in (("rts", lambda: bench_rts(a.seeds)), ("outliers", lambda: bench_outliers(a.seeds)),
                     ("isam", lambda: bench_isam(a.tracks)),
                     ("real", (lambda: {}) if a.skip_real else bench_real),
                     ("crossings", lambda: bench_crossings(a.min_crossings))):
        t0 = time.perf_counter()
        out.update(fn())
        _log(f"{name}: {time.perf_counter() - t0:.1f} s")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
