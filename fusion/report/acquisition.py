"""The bearing-time record (BTR) of a cube with the line ``fusion acquire`` found.

The BTR is the cube's power in one frequency bin against bearing (cosine-spaced beams mapped to
degrees from the forward axis, :func:`fusion.geometry.bearing_from_beam`) and time (s, 0 at the
latest scan). The acquisition's result -- bearing and bearing rate at the latest scan -- is drawn
as the constant-rate line that ends there.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import bearing_from_beam
from fusion.report.figures import new_figure
from fusion.types import Cube

__all__ = ["acquisition_figure", "beam_edges_deg", "btr_bin", "btr_db", "read_acquisition"]


def read_acquisition(doc: Any, *, source: str) -> dict[str, float | bool]:
    """The numbers of a ``fusion acquire`` result (a JSON object), checked.

    Parameters
    ----------
    doc : object
        The parsed JSON.
    source : str, keyword-only
        Its file name, for messages.

    Returns
    -------
    dict
        ``bearing_deg`` (deg from the forward axis), ``bearing_rate_deg_per_min``, ``snr_db``
        and ``default_used``.

    Raises
    ------
    ValueError
        A key missing, or a value that is not a finite number (or, for ``default_used``, not a
        boolean).
    """
    if not isinstance(doc, Mapping):
        raise ValueError(f"{source}: expected a JSON object (fusion acquire output)")
    out: dict[str, float | bool] = {}
    for key in ("bearing_deg", "bearing_rate_deg_per_min", "snr_db"):
        v = doc.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
            raise ValueError(f"{source}: '{key}' must be a finite number, got {v!r}")
        out[key] = float(v)
    used = doc.get("default_used", False)
    if not isinstance(used, bool):
        raise ValueError(f"{source}: 'default_used' must be true or false, got {used!r}")
    out["default_used"] = used
    return out


def btr_bin(cube: Cube, freq_hz: float | None) -> int:
    """The frequency bin of the BTR: nearest `freq_hz`, else the one with the strongest line.

    Parameters
    ----------
    cube : Cube
    freq_hz : float or None
        Clicked frequency, Hz; must lie within the band of the bins (half a bin beyond either
        end). ``None``: the bin whose time-averaged beam power has the largest peak-to-median
        ratio across beams.

    Returns
    -------
    int
    """
    f = cube.freqs
    if freq_hz is None:
        mean = cube.power.mean(axis=0)  # (beams, bins)
        contrast = mean.max(axis=0) / np.maximum(np.median(mean, axis=0), 1e-300)
        return int(np.argmax(contrast))
    df = float(np.median(np.diff(f))) if f.size > 1 else 0.0
    if not f[0] - 0.5 * df <= freq_hz <= f[-1] + 0.5 * df:
        raise ValueError(f"--freq-hz {freq_hz:g} Hz is outside the band {f[0] - 0.5 * df:g}.."
                         f"{f[-1] + 0.5 * df:g} Hz of the cube")
    return int(np.argmin(np.abs(f - freq_hz)))


def btr_db(cube: Cube, k: int) -> NDArray[np.float64]:
    """Power of bin `k` in dB over the bin's median, shape (scans, beams) (floor -30 dB)."""
    power = cube.power[:, :, k]
    return 10.0 * np.log10(np.maximum(power / max(float(np.median(power)), 1e-300), 1e-3))


def beam_edges_deg(n_beams: int) -> NDArray[np.float64]:
    """Bearing of the edges between beams (half-beam steps), deg, shape (n_beams + 1,)."""
    edges = np.arange(n_beams + 1, dtype=float) - 0.5
    return np.degrees(bearing_from_beam(np.clip(edges, 0.0, n_beams - 1.0), n_beams))


def acquisition_figure(cube: Cube, result: Mapping[str, float | bool], *, freq_hz: float | None,
                       lag_s: float = 0.0, title: str) -> Any:
    """BTR of one bin of `cube` with the acquired constant-rate line.

    Parameters
    ----------
    cube : Cube
        The cube given to ``fusion acquire`` (power linear).
    result : mapping
        :func:`read_acquisition` of its output.
    freq_hz : float or None, keyword-only
        The clicked frequency, Hz (``None``: see :func:`btr_bin`).
    lag_s : float, keyword-only
        The ``--display-lag-s`` of the acquisition, s: the reported bearing is the line's bearing
        ``lag_s`` after the latest scan.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
        Power (dB over the bin's median) against bearing (deg) and time (s, latest scan 0).
    """
    k = btr_bin(cube, freq_hz)
    db = btr_db(cube, k)
    n_scans, n_beams = db.shape
    t = (np.arange(n_scans + 1, dtype=float) - n_scans + 0.5) * cube.scan_period
    fig, ax = new_figure(size=(8.0, 6.5))
    im = ax.pcolormesh(beam_edges_deg(n_beams), t, db, cmap="viridis", shading="flat")
    fig.colorbar(im, ax=ax, label="power over the bin's median, dB")
    tl = np.linspace(t[0] + 0.5 * cube.scan_period, 0.0, 200)
    rate_deg_s = float(result["bearing_rate_deg_per_min"]) / 60.0
    line = float(result["bearing_deg"]) + rate_deg_s * (tl - lag_s)
    inside = (line >= 0.0) & (line <= 180.0)
    default = " (defaults used)" if result["default_used"] else ""
    ax.plot(np.where(inside, line, np.nan), tl, "r-", lw=1.8,
            label=f"acquired: {result['bearing_deg']:.1f} deg, "
                  f"{result['bearing_rate_deg_per_min']:.1f} deg/min{default}")
    ax.plot(float(result["bearing_deg"]), lag_s, "r*", ms=12, mec="w")
    ax.set_xlim(0.0, 180.0)
    ax.set_ylim(t[0], max(t[-1], lag_s))  # latest scan at the top
    ax.set_xlabel("bearing from the forward axis, deg")
    ax.set_ylabel("time from the latest scan, s")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"{title}\nBTR at {cube.freqs[k]:.2f} Hz, SNR {result['snr_db']:.1f} dB "
                 "(1 Hz band)")
    return fig
