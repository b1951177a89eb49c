"""Demo part ``clicks-scenario``: whale clicks to validated TDOAs and sources, with figures.

A seeded three-whale scenario on hydrophones standing a few metres above the sea floor (floor
and surface echoes, ``fusion simulate clicks --echo both``) is written in the project's file
formats, read back as a user's recording would be, its replica, echo suppression and sea floor
decided from the recording as ``fusion localize`` does
(:func:`fusion.pipelines.from_recording.decide_from_recording`), and run through
:class:`fusion.pipelines.localization.ClickLocalization` (click detection, smoothed click maps,
GMM validation, sub-sample refinement, association across time and pairs, competing sources on
the factor graph). The truth is used only to score and to draw.

Figures: ``clicks_correlogram.png`` (the smoothed-click-map correlation of one pair over the
windows -- FIG. 7 of the method text -- with the accepted TDOAs and the truth),
``clicks_tdoas.png`` (every pair's TDOAs against time: valid, rejected, truth),
``clicks_surfaces.png`` (eq. 17 beside eq. 18 in plan view at the estimated depth of one window,
with the true and estimated positions) and ``clicks_tracks.png`` (the tracks smoothed on the
factor graph with the per-window fixes, in plan view and depth against time, over the whales'
true tracks). ``localization.json`` holds the windows and tracks as ``fusion localize`` writes
them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fusion.io import read_array, read_audio, write_json
from fusion.localization.intensity import intensity_volume
from fusion.localization.search_grid import SearchRegion
from fusion.localization.surface_paths import surface_paths
from fusion.localization.window_tdoas import WindowTdoas
from fusion.metrics.localization import match_fixes
from fusion.pipelines.clicks.chunks import FEW_TDOAS
from fusion.report.figures import ensure_visible, sigma_band

__all__ = ["run_demo"]

#: A whale is found, and a fix is not false, within this distance, m (fixes farther are errors
#: of the count, not of the median error).
FOUND_M = 50.0


def _truth_tau(labels, pair, t_mid: float, t0: float, t1: float) -> np.ndarray:
    return labels.tau_at(pair, t_mid, t0, t1)


def _truth_at(sc, t_mid: float) -> np.ndarray:
    """Each whale's position at the emission whose arrivals are centred on `t_mid` (to draw)."""
    out = []
    for s in sc.sources:
        p = s.position_at([t_mid])[0]
        for _ in range(3):  # emission time = t_mid - mean travel time (fixed point)
            r = np.linalg.norm(sc.sensors.positions - p, axis=1).mean() / sc.sensors.sound_speed
            p = s.position_at([t_mid - r])[0]
        out.append(p)
    return np.array(out)


def _window_tdoas(lw, pipe, array) -> WindowTdoas:
    """The valid TDOAs of a localized window as the localizer saw them (sigma floor added)."""
    w, idx = lw.window, lw.valid_index
    d = [w.tdoas[k] for k in idx]
    sig = np.hypot([t.sigma_s for t in d], pipe.sigma_floor_s)
    return WindowTdoas(array.positions, np.array([t.pair for t in d]), [t.tau_s for t in d],
                       sig, c=array.sound_speed, alpha=w.alpha[np.ix_(idx, idx)])


def _draw_surfaces(plt, path: Path, done, pipe, array, sc) -> float | None:
    """Eq. (17) and eq. (18) side by side on a plane at the estimated depth of one window.

    The window drawn is the one with the most sources (then the most valid TDOAs); the plane is
    at the depth of its first source. True positions (o, from the simulator) and estimated ones
    (x) are marked. Returns the window's start time, s (None when no window has a source).
    """
    best = max((lw for lw in done if lw.output is not None and lw.output.sources),
               key=lambda lw: (len(lw.output.sources), lw.valid_index.size), default=None)
    if best is None:
        return None
    tdoas = _window_tdoas(best, pipe, array)
    localizer = pipe.localizer_for(array)  # the direct-path reading every window starts with
    surface_z = localizer.surface_z
    groups = None
    if surface_z is not None:  # as the localizer reads them: direct and surface-reflected paths
        paths = surface_paths(tdoas, surface_z)
        tdoas, groups = paths.tdoas, paths.measured
    srcs = np.array([s.position for s in best.output.sources])
    z = float(srcs[0, 2])
    region = localizer.region
    grid = SearchRegion(extent_factor=region.extent_factor, water_column=region.water_column,
                        max_points=220 * 220).plane(array.positions, z)
    truth = _truth_at(sc, 0.5 * (best.window.t_start + best.window.t_end))
    ext = [grid.x[0], grid.x[-1], grid.y[0], grid.y[-1]]
    fig, axes = plt.subplots(1, 2, figsize=(14, 6.2))
    for ax, eq, label in ((axes[0], 17, "eq. 17: sum of the TDOA hyperbolas"),
                          (axes[1], 18, "eq. 18: association-weighted pairs")):
        vol = intensity_volume(tdoas, grid, equation=eq, groups=groups)
        im = ax.imshow(vol.values[:, :, 0].T, origin="lower", extent=ext, cmap="magma",
                       aspect="equal")
        fig.colorbar(im, ax=ax, shrink=0.8, label="intensity" if eq == 17
                     else "intensity (sum alpha I I)")
        ax.plot(array.positions[:, 0], array.positions[:, 1], "c^", ms=8, label="hydrophones")
        ax.plot(truth[:, 0], truth[:, 1], "o", mfc="none", mec="lime", ms=14, mew=2,
                label="true (simulator)")
        ax.plot(srcs[:, 0], srcs[:, 1], "x", color="w", ms=10, mew=2, label="estimated")
        ax.set(xlabel="x east (m)", ylabel="y north (m)", title=label)
    axes[0].legend(loc="lower left", fontsize=8)
    fig.suptitle(f"window {best.window.t_start:.0f}-{best.window.t_end:.0f} s, "
                 f"{best.valid_index.size} valid TDOAs"
                 + (" read along direct and surface-reflected paths" if groups is not None
                    else "") + f", plane at the estimated depth z = {z:.0f} m")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return float(best.window.t_start)


def _flagged(fix) -> bool:
    """A fix the output flags: unobservable, mirror-ambiguous, or on too few TDOAs to check."""
    return bool(not fix.observable or fix.mirror_ambiguous or fix.tdoas_used <= FEW_TDOAS)


def _draw_tracks(plt, path: Path, done, tracks, array, sc) -> None:
    """Tracks (smoothed, per-window fixes) over the true tracks: plan view and depth vs time."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(14, 6))
    for k, s in enumerate(sc.sources):
        p = s.positions
        ax1.plot(p[:, 0], p[:, 1], "-", lw=6, color="0.8", label="true" if k == 0 else None)
        ax2.plot(s.emission_times, -p[:, 2], "-", lw=6, color="0.8")  # depth, m (down)
    fixes = [(0.5 * (lw.window.t_start + lw.window.t_end), f) for lw in done
             if lw.output is not None for f in lw.output.sources]
    for m, f in fixes:
        mark = "rx" if _flagged(f) else "k+"
        ax1.plot(f.position[0], f.position[1], mark, ms=7)
        ax2.plot(m, -f.position[2], mark, ms=7)
    for tr in tracks:
        col = f"C{tr.track_id % 10}"
        ax1.plot(tr.positions[:, 0], tr.positions[:, 1], "o-", color=col, ms=3,
                 label=f"track {tr.track_id}")
        sz = np.sqrt(np.clip(tr.covariances[:, 2, 2], 0.0, None))
        ax2.plot(tr.times, -tr.positions[:, 2], "o-", color=col, ms=3)
        sigma_band(ax2, tr.times, -tr.positions[:, 2], sz, color=col, alpha=0.25)
    ax1.plot([], [], "k+", label="fix per window")
    ax1.plot([], [], "rx", label="flagged (unobservable, mirror-ambiguous or <= 3 TDOAs)")
    # zoom on the whales: their true tracks and the fixes near them, with a margin
    pts = np.vstack([s.positions for s in sc.sources])
    near = [f.position for _, f in fixes if np.min(np.linalg.norm(pts - f.position, axis=1)) < 200]
    pts = np.vstack([pts] + near + [tr.positions for tr in tracks])
    pad = max(50.0, 0.15 * float(np.ptp(pts[:, :2], axis=0).max()))
    ax1.set(xlim=(pts[:, 0].min() - pad, pts[:, 0].max() + pad),
            ylim=(pts[:, 1].min() - pad, pts[:, 1].max() + pad),
            xlabel="x east (m)", ylabel="y north (m)", aspect="equal",
            title="plan view (zoomed on the whales)")
    ax1.legend(fontsize=8)
    zpad = max(20.0, 0.15 * float(np.ptp(pts[:, 2])))
    ax2.set(ylim=(-pts[:, 2].min() + zpad, -pts[:, 2].max() - zpad), xlabel="time, s",
            ylabel="depth, m", title="depth against time (band: smoothed 1 sigma)")
    fig.suptitle(f"{len(tracks)} tracks smoothed on a constant-velocity factor graph; "
                 "grey: the simulator's whales")
    fig.tight_layout()
    ensure_visible(fig)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def run_demo(out_dir: Path, *, seed: int) -> dict[str, Any]:
    """Run the click localization on a seeded scenario; write the result and four figures.

    A demo part (:mod:`fusion.demos`: `out_dir`, `seed`).

    Returns
    -------
    dict
        Windows, candidate and valid TDOAs, the fraction of valid TDOAs that are true (SCM delay
        within 3 ms of a true TDOA), the median |error| of valid refined TDOAs (us) and their
        median CRB (us), sources reported, how many of them are flagged (unobservable,
        mirror-ambiguous or on <= 3 TDOAs; not scored) and the median 3-D error of the other
        sources matched to a whale within 50 m, the number of tracks, the start of the window
        whose surfaces are drawn (s), and what was decided from the recording (replica, bottom
        echoes, sea floor).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.pipelines.clicks import ClickFrontEnd
    from fusion.pipelines.clicks.training import label_windows, scenario_labels
    from fusion.pipelines.localization import (
        ClickLocalization,
        LocalizerSettings,
        result_document,
        track_windows,
    )
    from fusion.pipelines.sound_speed import calibrate_speed
    from fusion.simulate.clicks import simulate_clicks, write_click_scenario

    out = Path(out_dir)
    # hydrophones 1-20 m above the sea floor: floor and surface echoes on every sensor
    sc = simulate_clicks(seed=seed, n_sensors=5, n_sources=3, duration_s=24.0, snr_db=30.0,
                         echo="both")
    write_click_scenario(out / "scenario", sc)
    array = read_array(out / "scenario" / "array.json")
    audio, fs = read_audio(out / "scenario" / "audio.flac", n_channels=array.n_sensors)

    # fusion localize's defaults: replica, echo suppression and sea floor decided from the
    # recording (the library chain's own step), surface paths per window
    pipe, decided = ClickLocalization(
        front_end=ClickFrontEnd(),
        localizer=LocalizerSettings()).with_recording_decisions(
            audio, fs, array, span="the demo recording")
    step = int(round(pipe.front_end.hop_s * fs))
    blocks = ((a / fs, audio[a:a + step]) for a in range(0, audio.shape[0], step))
    done = list(pipe.iter_windows(blocks, fs=fs, sensors=array, duration_s=audio.shape[0] / fs))

    windows = [d.window for d in done]
    labels = scenario_labels(sc)
    true = label_windows(windows, labels, tol_s=3e-3, coarse=True)
    valid = np.concatenate([[t.valid for t in w.tdoas] for w in windows])
    is_true = np.concatenate(true)
    errs, crbs = [], []
    for w in windows:
        mid = 0.5 * (w.t_start + w.t_end)
        for t in w.valid_tdoas:
            ref = _truth_tau(labels, t.pair, mid, w.t_start, w.t_end)
            if ref.size and np.isfinite(t.crb_s):
                e = float(np.min(np.abs(ref - t.tau_s)))
                if e < 1e-3:
                    errs.append(e)
                    crbs.append(t.crb_s)

    # sources against the whales' positions at the emission centred on the window
    # found (a whale with an unflagged fix within FOUND_M) and false (an unflagged fix farther
    # than that from every whale) are counted over the windows, before any error is quoted
    src_err = []
    n_sources = n_flagged = whale_windows = found = false = 0
    for d in done:
        if d.output is None:
            continue
        mid = 0.5 * (d.window.t_start + d.window.t_end)
        truth = _truth_at(sc, mid)
        whale_windows += len(truth)
        kept = []
        for s in d.output.sources:
            n_sources += 1
            if _flagged(s):  # shown apart, not scored as a fix
                n_flagged += 1
                continue
            kept.append(s.position)
        m = match_fixes(truth, np.array(kept).reshape(-1, 3), within_m=FOUND_M, near_m=FOUND_M)
        found += m.found
        false += m.false
        src_err += list(m.errors_m)

    # ---- figure 1: correlogram of the pair with the most valid TDOAs (FIG. 7)
    counts: dict[tuple[int, int], int] = {}
    for w in windows:
        for t in w.valid_tdoas:
            counts[t.pair] = counts.get(t.pair, 0) + 1
    pair = max(counts, key=counts.get) if counts else (0, 1)
    rows, lags = [], None
    for w in windows:
        corr = pipe.front_end.correlator.correlate(list(w.clicks), t0_s=w.t_start, sensors=array,
                                                   pairs=[pair])
        rows.append(corr.values[0])
        lags = corr.lags_s
    img = np.array(rows)
    mids = [0.5 * (w.t_start + w.t_end) for w in windows]
    fig, ax = plt.subplots(figsize=(8, 5))
    keep = np.abs(lags) <= float(np.max(np.abs(corr.max_delay_s))) * 1.05
    ax.imshow(img[:, keep].T, aspect="auto", origin="lower", cmap="viridis",
              extent=[mids[0] - 1, mids[-1] + 1, lags[keep][0], lags[keep][-1]])
    for w, m in zip(windows, mids, strict=True):
        for t in w.tdoas:
            if t.pair == pair:
                ax.plot(m, t.tau_s, "o" if t.valid else "x", color="w" if t.valid else "r", ms=5)
    for s in sc.sources:
        arr = s.arrival_times
        ax.plot(arr[:, pair[0]], arr[:, pair[0]] - arr[:, pair[1]], "--", color="orange", lw=1)
    ax.set(xlabel="time (s)", ylabel=f"delay tau{pair[0]}{pair[1]} (s)",
           title=f"smoothed click map correlation, pair {pair} (o valid, x rejected, -- truth)",
           xlim=(mids[0] - 1, mids[-1] + 1))
    fig.tight_layout()
    fig.savefig(out / "clicks_correlogram.png", dpi=90)
    plt.close(fig)

    # ---- figure 2: TDOAs against time, every pair
    pairs = array.pairs()
    ncol = 5
    nrow = int(np.ceil(len(pairs) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(16, 3.2 * nrow), squeeze=False)
    for ax, pr in zip(axes.ravel(), pairs, strict=False):
        for s in sc.sources:
            arr = s.arrival_times
            ax.plot(arr[:, pr[0]], (arr[:, pr[0]] - arr[:, pr[1]]) * 1e3, "-", color="0.75", lw=2)
        for w, m in zip(windows, mids, strict=True):
            for t in w.tdoas:
                if t.pair == pr:
                    ax.plot(m, t.tau_s * 1e3, "o" if t.valid else "x",
                            color="tab:blue" if t.valid else "tab:red", ms=4)
        ax.set(title=f"pair {pr}", xlabel="time (s)", ylabel="TDOA (ms)")
    for ax in axes.ravel()[len(pairs):]:
        ax.axis("off")
    fig.suptitle("TDOAs per window: o valid, x rejected; grey: truth per click")
    fig.tight_layout()
    fig.savefig(out / "clicks_tdoas.png", dpi=80)
    plt.close(fig)

    # ---- figure 3: eq. 17 against eq. 18 in plan view at the estimated depth
    tracks = track_windows(done)
    doc = result_document(done, tracks=tracks)
    # the recording's sound speed from all its fixes, as fusion localize does after its windows
    speed = calibrate_speed(doc["windows"], array.positions, array.sound_speed)
    doc["windows"] = [speed.apply(w) for w in doc["windows"]]
    write_json(out / "localization.json", doc)
    surf = _draw_surfaces(plt, out / "clicks_surfaces.png", done, pipe, array, sc)

    # ---- figure 4: tracks in plan view and depth against time
    _draw_tracks(plt, out / "clicks_tracks.png", done, tracks, array, sc)

    return {
        "windows": len(windows),
        "candidate_tdoas": int(valid.size),
        "valid_tdoas": int(valid.sum()),
        "valid_true_fraction": round(float(is_true[valid].mean()), 3) if valid.any() else None,
        "tdoa_abs_error_median_us": round(float(np.median(errs)) * 1e6, 3) if errs else None,
        "tdoa_crb_median_us": round(float(np.median(crbs)) * 1e6, 3) if crbs else None,
        "sources": n_sources,
        "sources_flagged": n_flagged,
        "whales_found": f"{found}/{whale_windows}",
        "false_fixes": false,
        "source_error_median_m": round(float(np.median(src_err)), 2) if src_err else None,
        "tracks": len(tracks),
        "surface_window_s": surf,
        "replica_estimated": decided.replica is not None,
        "bottom_echoes": decided.echoes.describe(),
        "sea_floor_z": decided.settings.sea_floor_z,
        "sound_speed_mps": round(speed.speed_mps, 2),
        "sound_speed_source": speed.record()["source"],
    }
