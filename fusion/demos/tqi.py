"""Demo part ``tqi``: the track quality indicator on a simulated track and on a cube tracking run.

One simulated track passes through strong, near-threshold, strong again and lost conditions;
the TQI with and without hysteresis is drawn over its amplitudes, residuals and SLLRs, and the
update at which each declares the loss is measured (:func:`fusion.metrics.tqi.declaration_lag`).
Then the passive pipeline tracks a 25 deg/min line in a simulated cube and reports its TQI states.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusion.io import write_table
from fusion.metrics.tqi import declaration_lag
from fusion.passive.quality import TrackQualityIndicator

__all__ = ["run_demo"]


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part ``tqi``: TQI timeline of a simulated track, and a cube tracking run.

    Writes ``amplitudes.csv``, ``tqi.csv`` and ``tqi_timeline.png`` (amplitude, residual, SLLRs,
    state with and without hysteresis) for one simulated track passing through strong,
    near-threshold, strong again and lost; then simulates a 25 deg/min line in a beam/frequency/
    time cube, initialises the bearing tracker from the acquisition, tracks 60 scans and writes
    ``cube_track.csv`` and ``cube_track.png``.

    A demo part (:mod:`fusion.demos`: `out_dir`, `seed`).

    Returns
    -------
    dict
        Measured numbers: state changes with/without hysteresis, update at which each declared
        the loss, and the cube run's final bearing error and TQI state counts.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.passive.quality import LABELS
    from fusion.simulate.amplitudes import condition_snr_db, draw_amplitudes, draw_residuals

    out_dir = Path(out_dir)
    rng = np.random.default_rng(seed)
    plan = [("strong", 50), ("near_strong", 80), ("near_lost", 80), ("strong", 40), ("lost", 50)]
    cond = np.concatenate([np.full(m, c) for c, m in plan])
    snr = np.array([condition_snr_db(c) for c in cond])
    amp = draw_amplitudes(snr, rng=rng)
    res = draw_residuals(snr, rng=rng)
    t = np.arange(cond.size, dtype=float)
    h1 = TrackQualityIndicator().run(amp, res)
    h0 = TrackQualityIndicator(hysteresis=False).run(amp, res)
    write_table(out_dir / "amplitudes.csv", {"track_id": np.zeros(t.size, dtype=np.int64),
                                             "time": t, "amplitude": amp, "residual": res})
    write_table(out_dir / "tqi.csv", {"time": t, "condition": cond,
                                      "tqi": h1.labels()[:, 0],
                                      "tqi_single_threshold": h0.labels()[:, 0],
                                      "sllr0": h1.sllr0[:, 0], "sllr1": h1.sllr1[:, 0]})
    onset = int(np.flatnonzero(cond == "lost")[0])

    def first_lost(h) -> int:
        lag = float(declaration_lag(h.state, onset)[0])
        return onset + int(lag) if np.isfinite(lag) else -1

    fig, ax = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
    ax[0].plot(t, 10.0 * np.log10(np.maximum(amp, 1e-3)), ".", ms=3)  # as fusion report draws it
    ax[0].set_ylabel("amplitude, dB (noise mean 0 dB)")
    ax[1].plot(t, res, ".", ms=3, color="0.6", label="residual")
    ax[1].plot(t, h1.residual_deg[:, 0], label="smoothed ES")
    ax[1].plot(t, h1.err_max_deg[:, 0], "k--", lw=0.8, label="ERR_max")
    ax[1].plot(t, -h1.err_max_deg[:, 0], "k--", lw=0.8)
    ax[1].set_ylabel("residual, deg")
    ax[1].legend(loc="upper right", fontsize=7)
    ax[2].plot(t, h1.sllr0[:, 0], label="SLLR_0")
    ax[2].plot(t, h1.sllr1[:, 0], label="SLLR_1")
    for y in (-3.5, 1.75, 7.0):
        ax[2].axhline(y, color="k", lw=0.6, ls=":")
    ax[2].set_ylabel("SLLR")
    ax[2].legend(loc="upper right", fontsize=7)
    ax[3].step(t, h0.state[:, 0] - 0.08, where="post", color="0.6", label="single thresholds")
    ax[3].step(t, h1.state[:, 0], where="post", label="hysteresis")
    ax[3].set_yticks(range(4), LABELS)
    ax[3].set_xlabel("update")
    ax[3].legend(loc="upper right", fontsize=7)
    edges = np.cumsum([0] + [m for _, m in plan])
    for a in ax:
        for x0 in edges[:-1]:
            a.axvline(x0, color="r", lw=0.5)
    for (c, _), x0 in zip(plan, edges[:-1], strict=True):
        ax[0].text(x0 + 1, ax[0].get_ylim()[1], c, va="top", fontsize=7)
    fig.suptitle("Track quality indicator with hysteresis")
    fig.tight_layout()
    fig.savefig(out_dir / "tqi_timeline.png", dpi=100)
    plt.close(fig)
    summary: dict = {
        "changes_hysteresis": int(h1.n_changes()[0]),
        "changes_single_threshold": int(h0.n_changes()[0]),
        "loss_onset_update": onset,
        "lost_declared_hysteresis": first_lost(h1),
        "lost_declared_single_threshold": first_lost(h0),
    }
    summary.update(_demo_cube(out_dir, seed=seed, plt=plt))
    return summary


def _demo_cube(out_dir: Path, *, seed: int, plt) -> dict:
    """The passive pipeline (acquisition -> fixed-lag track -> TQI) on a simulated cube."""
    from fusion.passive.acquisition import Acquisition
    from fusion.passive.crossing import CrossingDetector
    from fusion.passive.quality import TrackQuality
    from fusion.pipelines.passive import PassivePipeline
    from fusion.pipelines.passive.types import Click, scans_of
    from fusion.simulate.cube import simulate_cube

    window, n_track = 60, 60
    sc = simulate_cube(seed=seed, n_scans=window + n_track + 1, bearing0_deg=50.0,
                       bearing_rate_deg_per_min=25.0, snr_db=6.0)
    c = sc.cube
    latest = window - 1
    click = Click(int(np.floor(sc.beam_track[latest] + 0.5)), sc.click_freq)
    pipe = PassivePipeline(acquisition=Acquisition(), tqi=TrackQualityIndicator(),
                           crossing=CrossingDetector(J=12, K=5.0), acquisition_scans=window)
    ups = []  # the track's filtered state, amplitude, residual and TQI after every scan
    for i, scan in enumerate(scans_of(c)):
        if i > latest + n_track:
            break
        ups += pipe.step(scan, clicks=[click] if i == 0 else ()).updates
    start = pipe.result().tracks[0].start
    scan_k = np.array([int(round(u.time / c.scan_period)) for u in ups])
    brg = np.array([u.bearing_deg for u in ups])
    labels = np.array([u.tqi for u in ups])
    truth = sc.shown_bearing_deg[scan_k]
    write_table(out_dir / "cube_track.csv", {
        "time": np.array([u.time for u in ups]), "bearing_deg": brg,
        "bearing_rate_deg_per_min": np.array([u.bearing_rate_deg_per_min for u in ups]),
        "true_bearing_deg": truth, "amplitude": np.array([u.amplitude for u in ups]),
        "residual": np.array([u.residual_deg for u in ups]), "tqi": labels})
    # BTR in the units `fusion report` uses (bearing deg across, time s up, dB over the bin's
    # median); the bearing error below on its own time axis (no axis shared with the BTR)
    from fusion.report.acquisition import beam_edges_deg, btr_bin, btr_db

    db = btr_db(c, btr_bin(c, sc.click_freq))
    t_edges = (np.arange(c.n_scans + 1) - 0.5) * c.scan_period
    times = scan_k * c.scan_period
    fig, ax = plt.subplots(1, 2, figsize=(12, 6), gridspec_kw={"width_ratios": [1.6, 1]})
    im = ax[0].pcolormesh(beam_edges_deg(c.n_beams), t_edges, db, cmap="viridis",
                          shading="flat")
    fig.colorbar(im, ax=ax[0], label="power over the bin's median, dB")
    ax[0].plot(brg, times, "r.", ms=3, label="tracker")
    ax[0].axhline(latest * c.scan_period, color="w", lw=0.8, ls="--",
                  label="end of the acquisition window")
    ax[0].set_xlim(0.0, 180.0)
    ax[0].set_xlabel("bearing from the forward axis, deg")
    ax[0].set_ylabel("time, s")
    ax[0].legend(loc="upper right", fontsize=7)
    ax[1].plot(brg - truth, times)
    ax[1].axvline(0.0, color="k", lw=0.6)
    ax[1].set_xlabel("bearing error, deg")
    ax[1].set_ylabel("time, s")
    ax[1].set_ylim(ax[0].get_ylim())
    ax[1].grid(alpha=0.3)
    fig.suptitle("passive chain on a simulated cube: BTR with the track, and its bearing error")
    fig.tight_layout()
    fig.savefig(out_dir / "cube_track.png", dpi=100)
    plt.close(fig)
    return {
        "cube_acq_rate_deg_per_min": round(float(start.bearing_rate_deg_per_min), 2),
        "cube_true_rate_deg_per_min": 25.0,
        "cube_final_bearing_error_deg": round(float(brg[-1] - truth[-1]), 3),
        "cube_rms_bearing_error_deg": round(float(np.sqrt(np.mean((brg - truth) ** 2))), 3),
        "cube_never_lost": bool(np.all(labels != TrackQuality.LOST.label)),
        "cube_updates_strong": int(np.sum(labels == TrackQuality.STRONG.label)),
        "cube_updates_low_snr": int(np.sum(labels == TrackQuality.LOW_SNR.label)),
    }
