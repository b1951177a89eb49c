"""Demo part ``acquisition``: acquire a high bearing-rate narrowband line from a simulated cube.

A seeded beam/frequency/time cube with one line moving at 35 deg/min is acquired from an
operator's click (:class:`fusion.passive.acquisition.Acquisition`); the part writes the result
against the truth and the integrated-bandwidth bearing-time record with the best trace.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusion.io import write_json
from fusion.simulate.cube import simulate_cube

__all__ = ["run_demo"]


def run_demo(out_dir: Path, *, seed: int) -> dict[str, float | bool]:
    """Demo part: acquire a high bearing-rate line; write ``btr.png`` and ``result.json``.

    A demo part (:mod:`fusion.demos`: `out_dir`, `seed`).

    Returns
    -------
    dict
        True and estimated bearing (deg) and bearing rate (deg/min), the SNR estimate and whether
        the defaults were used.
    """
    from fusion.passive.acquisition import Acquisition
    from fusion.report.acquisition import acquisition_figure
    from fusion.report.figures import FigureWriter

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = simulate_cube(seed=seed, bearing0_deg=55.0, bearing_rate_deg_per_min=35.0, snr_db=6.0,
                       lag_s=2.0)
    res = Acquisition(lag_s=2.0).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    write_json(out_dir / "result.json", {
        **res.to_json(),
        "truth_bearing_deg": sc.latest_bearing_deg,
        "truth_bearing_rate_deg_per_min": sc.bearing_rate_deg_per_min,
        "click_beam": sc.click_beam,
        "click_freq": sc.click_freq,
    })
    # the figure `fusion report` draws for `fusion acquire` (same axes and units), plus the truth
    fig = acquisition_figure(sc.cube, res.to_json(), freq_hz=sc.click_freq, lag_s=2.0,
                             title=f"fusion demo: acquisition (true rate "
                                   f"{sc.bearing_rate_deg_per_min:.1f} deg/min)")
    ax = fig.axes[0]
    n = sc.cube.power.shape[0]
    ax.plot(sc.shown_bearing_deg, (np.arange(n) - n + 1) * sc.cube.scan_period, "w:", lw=1.2,
            label="true bearing (as displayed)")
    ax.legend(loc="lower right", fontsize=8)
    FigureWriter(out_dir).save(fig, "btr.png")
    return {
        "true_bearing_deg": round(sc.latest_bearing_deg, 2),
        "bearing_deg": round(res.bearing_deg, 2),
        "true_rate_deg_per_min": round(sc.bearing_rate_deg_per_min, 2),
        "rate_deg_per_min": round(res.bearing_rate_deg_per_min, 2),
        "snr_db": round(res.snr_db, 2),
        "default_used": res.default_used,
    }
