"""Demo part ``tma``: bearings-only target motion analysis after an own-ship manoeuvre.

A seeded two-leg own-ship scenario (:func:`fusion.simulate.tma.simulate_tma`) is written in the
file formats and solved by :class:`fusion.passive.tma.BearingsOnlyTMA`; the part draws the plan
view with 2-sigma ellipses and scores the final state (:func:`fusion.metrics.localization.nees`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusion.io import write_table
from fusion.metrics.localization import nees
from fusion.passive.tma import BearingsOnlyTMA, OwnshipTrack
from fusion.simulate.tma import simulate_tma, write_scenario

__all__ = ["run_demo"]


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part: TMA after a two-leg own-ship manoeuvre; plan view with 2-sigma ellipses.

    Parameters
    ----------
    out_dir : Path
        Folder for ``bearings.csv``, ``ownship.csv``, ``truth.csv``, ``estimate.csv`` and
        ``tma.png``.
    seed : int, keyword-only
        Scenario seed.

    Returns
    -------
    dict
        ``final_range_error_pct``, ``final_position_error_m``, ``nees_4dof`` (final time),
        ``observable``, ``n_bearings``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.report.figures import covariance_ellipse, ensure_visible

    out_dir = Path(out_dir)
    write_scenario(out_dir, seed=seed)
    sc = simulate_tma(seed=seed)
    res = BearingsOnlyTMA(bearing_sigma_deg=sc.bearing_sigma_deg).estimate(
        sc.times, sc.bearings, OwnshipTrack(sc.ownship_times, sc.ownship_xy)
    )
    write_table(
        out_dir / "estimate.csv",
        {"time": res.times, "x": res.x, "y": res.y, "vx": res.vx, "vy": res.vy,
         "sigma_x": res.sigma_x, "sigma_y": res.sigma_y, "range": res.range},
    )
    err = res.states[-1] - sc.truth[-1]

    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(sc.ownship_xy[:, 0], sc.ownship_xy[:, 1], "k-", label="own-ship")
    ax.plot(sc.truth[:, 0], sc.truth[:, 1], "g-", lw=2, label="true target")
    ax.plot(res.x, res.y, "b--", label="TMA estimate")
    for k in np.linspace(0, res.times.size - 1, 6).astype(int):
        covariance_ellipse(ax, (res.x[k], res.y[k]), res.covariances[k, :2, :2], n_sigma=2.0,
                           color="b")
        ax.plot([res.ownship_xy[k, 0], sc.truth[k, 0]], [res.ownship_xy[k, 1], sc.truth[k, 1]],
                ":", color="0.6", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_title(f"Bearings-only TMA (seed {seed}): 2-sigma ellipses, dotted = bearings")
    ax.legend(loc="best")
    ensure_visible(fig)
    fig.savefig(out_dir / "tma.png", dpi=110)
    plt.close(fig)
    return {
        "final_range_error_pct": round(
            100 * float(abs(res.range[-1] - sc.true_range[-1]) / sc.true_range[-1]), 3),
        "final_position_error_m": round(float(np.hypot(*err[:2])), 1),
        "nees_4dof": round(nees(err, res.covariances[-1]), 3),
        "observable": bool(res.observable),
        "n_bearings": int(res.times.size),
    }
