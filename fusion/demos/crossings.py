"""Demo part ``crossings``: alerts on a simulated bearing-time picture, coloured by track quality."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusion.geometry import wrap_deg
from fusion.io import write_table
from fusion.passive.crossing import detect_crossings
from fusion.passive.crossing.settings import crossing_settings
from fusion.pipelines.bearing_crossings import alert_columns


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part ``crossings``: alerts on a simulated bearing-time picture, with a figure.

    Simulates 8 tracks over 30 min (two crossing pairs, one through north, a near-miss pair,
    a parallel pair, two free tracks; K = 10 s, 0.5 deg noise), runs the detector with the
    settings `fusion crossings` chooses (:func:`~fusion.passive.crossing.crossing_settings`),
    writes ``bearings.csv``, ``alerts.csv`` and ``crossings.png`` into `out_dir` and returns
    the scores against the true crossings.

    The figure also shows each track's quality: every track gets a per-cell SNR history (a level
    between 0 and 15 dB with slow fading; one track fades out to noise in its last third), the
    tracker amplitudes and residuals of that history are drawn with
    :mod:`fusion.simulate.amplitudes`, and :class:`fusion.passive.quality.TrackQualityIndicator`
    colours each bearing sample by its TQI state (also written to ``tqi.csv``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.io import atomic_output
    from fusion.metrics.crossings import score_alerts
    from fusion.passive.quality import TrackQuality
    from fusion.report.figures import state_legend, tqi_markers
    from fusion.simulate.bearings import simulate_bearings

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = simulate_bearings(seed=seed, n_tracks=8, n_crossing_pairs=2, n_wrap_crossings=1,
                           n_near_miss_pairs=1, n_parallel_pairs=1, sample_period_s=10.0)
    cols = {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg}
    write_table(out_dir / "bearings.csv", cols)
    st = crossing_settings(sc.track_id, sc.time)  # what `fusion crossings` would choose
    J, K = st.J, st.period_s
    alerts = detect_crossings(cols, **st.detector_options())
    write_table(out_dir / "alerts.csv", alert_columns(alerts))
    score = score_alerts(alerts, list(sc.crossings), list(sc.non_crossing_pairs), J=J, K=K,
                         t_start=float(sc.truth_time[0]), t_end=float(sc.truth_time[-1]),
                         match_tol_s=st.horizon_s)

    tqi = _demo_track_quality(sc, seed=seed)
    write_table(out_dir / "tqi.csv", {"track_id": sc.track_id, "time": sc.time,
                                      "tqi": np.array([TrackQuality(q).label for q in tqi])})

    centred = wrap_deg  # north in the middle of the plot

    fig, ax = plt.subplots(figsize=(9, 6))
    t_min = sc.truth_time / 60.0
    for k in sc.track_ids:
        tb = centred(sc.truth_bearing_deg[k])
        tb[1:][np.abs(np.diff(tb)) > 180] = np.nan  # no line across the +-180 wrap
        ax.plot(tb, t_min, "-", lw=0.6, color="0.4", alpha=0.7)
        m = sc.track_id == k
        end = int(np.argmax(sc.time * m))
        ax.annotate(str(k), (centred(sc.bearing_deg[end]), sc.time[end] / 60.0), fontsize=7,
                    xytext=(3, 3), textcoords="offset points")
    labels = np.array([TrackQuality(q).label for q in tqi])
    for k in sc.track_ids:  # colour: the track; marker: its TQI state
        m = sc.track_id == k
        tqi_markers(ax, centred(sc.bearing_deg[m]), sc.time[m] / 60.0, labels[m],
                    color=f"C{int(k) % 10}", ms=2.5)
    state_legend(ax)
    for a in alerts:
        k = int(np.argmin(np.abs(sc.truth_time - a.t_cross)))
        b = centred(sc.truth_bearing_deg[a.track_a, k])
        if a.kind == "predicted":
            ax.plot(b, a.time / 60.0, "v", mfc="none", mec="k", ms=8)
        else:
            ax.plot(b, a.time / 60.0, "D", mfc="none", mec="k", ms=8)
    for c in sc.crossings:
        k = int(np.argmin(np.abs(sc.truth_time - c.t_cross)))
        ax.plot(centred(sc.truth_bearing_deg[c.track_a, k]), c.t_cross / 60.0, "o", mfc="none",
                mec="k", ms=10, lw=0.5)
    ax.plot([], [], "v", mfc="none", mec="k", label="predicted (at alert time)")
    ax.plot([], [], "D", mfc="none", mec="k", label="detected (at alert time)")
    ax.plot([], [], "o", mfc="none", mec="k", label="true crossing")
    ax.set_xlim(-180, 180)
    ax.set_xlabel("bearing, deg (clockwise from north, north in the middle)")
    ax.set_ylabel("time, min")
    ax.invert_yaxis()
    ax.set_title(f"Crossing prediction/detection, windows from {st.window_s:g} s, K={K:g} s "
                 f"(seed {seed})")
    ax.legend(fontsize=7, loc="lower left", ncol=2)
    fig.tight_layout()
    with atomic_output(out_dir / "crossings.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return {
        "true_crossings": score.n_crossings,
        "predicted_ahead": score.n_predicted_ahead,
        "detected": score.n_detected,
        "median_detection_delay_s": round(float(np.median(score.detection_delay_s)), 1)
        if score.n_detected else None,
        "non_crossing_pairs": score.n_non_crossing_pairs,
        "false_alert_pairs": score.n_false_pairs,
        "alerts": len(alerts),
        "tqi_fraction": {TrackQuality(q).label: round(float(np.mean(tqi == q)), 3)
                         for q in TrackQuality},
    }




def _demo_track_quality(sc, *, seed: int) -> np.ndarray:
    """TQI state of every bearing row of a simulated scenario (see :func:`run_demo`)."""
    from fusion.passive.quality import TrackQualityIndicator
    from fusion.simulate.amplitudes import draw_amplitudes, draw_residuals

    rng = np.random.default_rng(seed + 7919)
    times = np.unique(sc.time)
    ids = np.asarray(sc.track_ids)
    t = (times - times[0]) / max(times[-1] - times[0], 1.0)
    level = rng.uniform(0.0, 15.0, size=ids.size)
    phase = rng.uniform(0.0, 2 * np.pi, size=ids.size)
    snr = level[None, :] + 3.0 * np.sin(2 * np.pi * 1.5 * t[:, None] + phase[None, :])
    snr[t > 2 / 3, 0] = -np.inf  # the first track fades out to noise
    amp = draw_amplitudes(snr, rng=rng)
    res = draw_residuals(snr, rng=rng)
    states = TrackQualityIndicator().run(amp, res).state
    row_t = np.searchsorted(times, sc.time)
    row_k = np.searchsorted(ids, sc.track_id)
    return np.asarray(states)[row_t, row_k].astype(int)
