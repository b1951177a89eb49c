"""Pieces every figure of the report (and of the demo) shares: figures, saving, bands, ellipses.

Figures are :class:`matplotlib.figure.Figure` objects drawn on the Agg canvas: no pyplot state, no
window, nothing to close. :class:`FigureWriter` saves each one atomically
(:func:`fusion.io.atomic_output`) into the output folder and refuses to replace a file that is one
of the inputs.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "TQI_MARKERS",
    "FigureWriter",
    "bearing_band",
    "covariance_ellipse",
    "ensure_visible",
    "index_line",
    "new_figure",
    "no_wrap_line",
    "sigma_band",
    "state_legend",
    "tqi_markers",
]

logger = logging.getLogger(__name__)

#: Marker of each track-quality state. Colour is a track's identity in every figure; the state
#: is a marker shape, so the two never share a channel.
TQI_MARKERS: dict[str, str] = {"lost": "x", "uncertain": "^", "low_snr": "s", "strong": "o"}

#: Dots per inch of the PNG files.
DPI = 100
#: Smallest width, pixels, of an uncertainty band or ellipse in a saved figure: smaller ones are
#: drawn at this width, and the axes say so.
MIN_UNCERTAINTY_PX = 3.0
#: ``gid`` of the artists :func:`ensure_visible` may widen.
UNCERTAINTY_GID = "uncertainty"


def new_figure(nrows: int = 1, ncols: int = 1, *, size: tuple[float, float] = (8.0, 6.0),
               mosaic: Sequence[Sequence[str]] | None = None, **subplot_kw: Any) -> tuple[Any, Any]:
    """A figure on the Agg canvas and its axes (``Figure.subplots`` arguments).

    Parameters
    ----------
    nrows, ncols : int
        Grid of axes.
    size : (float, float), keyword-only
        Width and height, inches.
    mosaic : list of list of str, optional, keyword-only
        A layout for :meth:`matplotlib.figure.Figure.subplot_mosaic` instead of the grid; the
        axes are then a dict by name.
    **subplot_kw
        Passed to :meth:`matplotlib.figure.Figure.subplots` (``sharex``, ``squeeze``, ...).

    Returns
    -------
    (Figure, Axes or ndarray of Axes or dict of Axes)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    if mosaic is not None:
        return fig, fig.subplot_mosaic([list(r) for r in mosaic], **subplot_kw)
    return fig, fig.subplots(nrows, ncols, **subplot_kw)


class FigureWriter:
    """Saves figures as PNG files into one folder, atomically, never over an input.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when the first figure is written).
    inputs : iterable of path-like, keyword-only
        Files the report reads; a figure whose path is one of them (by any path or link) is
        refused.
    """

    def __init__(self, out_dir: str | os.PathLike[str], *,
                 inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
        self.out_dir = Path(out_dir)
        self.inputs = tuple(Path(p) for p in inputs)
        self.written: list[Path] = []
        #: file name -> its one-line reading (what it shows, with its counts), for ``summary.md``.
        self.readings: dict[str, str] = {}

    def save(self, fig: Any, name: str, reading: str = "") -> Path:
        """Write `fig` as ``out_dir/name`` (a ``.png`` name); return its path.

        `reading` is the figure's line in ``summary.md``: what it shows and its counts.

        Raises
        ------
        ValueError
            `name` would replace an input, or its path is a folder or a special file.
        """
        from fusion.io import atomic_output

        path = self.out_dir / name
        for p in self.inputs:
            try:
                same = os.path.samefile(path, p)
            except OSError:
                same = False
            if same:
                raise ValueError(f"{path}: is the input {p}; refusing to overwrite an input")
        ensure_visible(fig)
        with atomic_output(path, suffix=".png") as tmp:
            fig.savefig(tmp, format="png", dpi=DPI)
        self.written.append(path)
        self.readings[name] = reading
        logger.info("wrote %s", path)
        return path


def index_line(link: str, what: str, numbers: str = "") -> str:
    """One figure's line of a ``summary.md`` index (``fusion demo`` and ``fusion report``).

    Examples
    --------
    >>> index_line("tma/tma.png", "plan view", "observable=True")
    '- [tma.png](tma/tma.png): plan view — observable=True'
    """
    return f"- [{Path(link).name}]({link}): {what}" + (f" — {numbers}" if numbers else "")


def no_wrap_line(bearing_deg: ArrayLike, *, jump_deg: float = 180.0) -> NDArray[np.float64]:
    """Bearings with NaN where consecutive values jump by more than `jump_deg` (a 0/360 wrap).

    A line drawn through the result does not cross the whole plot at a wrap.

    Parameters
    ----------
    bearing_deg : array_like, shape (n,)
        Bearings in time order, deg.
    jump_deg : float, keyword-only
        Largest step that is not a wrap, deg.

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> no_wrap_line([350.0, 355.0, 2.0, 8.0]).tolist()
    [350.0, 355.0, nan, 8.0]
    """
    b = np.asarray(bearing_deg, dtype=float)
    return np.where(np.abs(np.diff(b, prepend=b[:1])) > jump_deg, np.nan, b)


def bearing_band(ax: Any, time_s: ArrayLike, bearing_deg: ArrayLike, sigma_deg: ArrayLike, *,
                 n_sigma: float = 1.0, label: str | None = None, **line_kw: Any) -> Any:
    """Draw a bearing track (bearing across, time down) with a ``n_sigma`` band around it.

    Parameters
    ----------
    ax : matplotlib Axes
    time_s : array_like, shape (n,)
        Times, s (increasing).
    bearing_deg : array_like, shape (n,)
        Bearings, deg; wraps (jumps over 180 deg) are not joined.
    sigma_deg : array_like, shape (n,)
        Standard deviation of each bearing, deg.
    n_sigma : float, keyword-only
        Half-width of the band in standard deviations.
    label : str, optional, keyword-only
        Legend label of the line.
    **line_kw
        Passed to ``ax.plot``.

    Returns
    -------
    matplotlib Line2D
        The track's line (its colour is the band's).
    """
    t = np.asarray(time_s, dtype=float)
    b = no_wrap_line(bearing_deg)
    s = n_sigma * np.asarray(sigma_deg, dtype=float)
    line, = ax.plot(b, t, label=label, **line_kw)
    sigma_band(ax, t, b, s, across="x", color=line.get_color())
    return line


def sigma_band(ax: Any, along: ArrayLike, centre: ArrayLike, half_width: ArrayLike, *,
               across: str = "y", color: Any = None, alpha: float = 0.3) -> Any:
    """Shade ``centre +- half_width`` along a curve (an uncertainty band).

    A band narrower than :data:`MIN_UNCERTAINTY_PX` in the saved figure is drawn at that width
    with a note on the axes (:func:`ensure_visible`).

    Parameters
    ----------
    ax : matplotlib Axes
    along : array_like, shape (n,)
        The curve's abscissa (time, usually).
    centre, half_width : array_like, shape (n,)
        Band centre and half-width, in the axes' units.
    across : {"y", "x"}, keyword-only
        The axis the band's width lies on ("x": ``fill_betweenx``, time down the y axis).
    color, alpha : keyword-only
        Fill colour and opacity.

    Returns
    -------
    matplotlib PolyCollection
    """
    a = np.asarray(along, dtype=float)
    c = np.asarray(centre, dtype=float)
    h = np.abs(np.asarray(half_width, dtype=float))
    fill = ax.fill_betweenx if across == "x" else ax.fill_between
    band = fill(a, c - h, c + h, color=color, alpha=alpha, lw=0)
    band.set_gid(UNCERTAINTY_GID)
    band._uncertainty = (a, c, h, across, color, alpha)  # redrawn wider by ensure_visible
    return band


def _pixels_per_unit(ax: Any) -> tuple[float, float]:
    """Pixels per data unit along x and y of `ax` as it will be saved (aspect applied)."""
    ax.apply_aspect()
    (x0, y0), (x1, y1) = ax.transData.transform([[0.0, 0.0], [1.0, 1.0]]) * (DPI / ax.figure.dpi)
    return abs(x1 - x0), abs(y1 - y0)


def ensure_visible(fig: Any, min_px: float = MIN_UNCERTAINTY_PX) -> int:
    """Widen uncertainty bands and ellipses thinner than `min_px` pixels; note it on the axes.

    Ellipses (:func:`covariance_ellipse`) and bands (:func:`sigma_band`) are checked at the
    figure's final layout; each one narrower than `min_px` is drawn `min_px` wide, and every axes
    holding one gets a note ("... drawn at N px minimum"), so that a reader sees the uncertainty
    is there and smaller than drawn. Returns the number widened (also stored as
    ``fig._widened``).

    Parameters
    ----------
    fig : matplotlib Figure
    min_px : float
        Smallest width, pixels.

    Returns
    -------
    int
    """
    from matplotlib.patches import Ellipse

    fig.canvas.draw()  # the final layout: limits and aspect as saved
    widened = 0
    for ax in fig.axes:
        px, py = _pixels_per_unit(ax)
        if not (np.isfinite(px) and np.isfinite(py)) or px == 0 or py == 0:
            continue
        here = 0
        per = min(px, py)
        for patch in list(ax.patches):
            if isinstance(patch, Ellipse) and patch.get_gid() == UNCERTAINTY_GID:
                w, h = patch.get_width(), patch.get_height()
                if min(w, h) * per < min_px:
                    patch.set_width(max(w, min_px / per))
                    patch.set_height(max(h, min_px / per))
                    here += 1
        for coll in list(ax.collections):
            data = getattr(coll, "_uncertainty", None)
            if data is None:
                continue
            a, c, h, across, color, alpha = data
            scale = px if across == "x" else py
            if np.nanmin(2.0 * h, initial=np.inf) * scale < min_px:
                coll.remove()
                wide = np.maximum(h, 0.5 * min_px / scale)
                fill = ax.fill_betweenx if across == "x" else ax.fill_between
                new = fill(a, c - wide, c + wide, color=color, alpha=alpha, lw=0)
                new.set_gid(UNCERTAINTY_GID)
                new._uncertainty = (a, c, wide, across, color, alpha)
                here += 1
        if here:
            ax.text(0.01, 0.01, f"uncertainty under {min_px:g} px drawn at {min_px:g} px",
                    transform=ax.transAxes, fontsize=7, color="0.3", ha="left", va="bottom",
                    gid="uncertainty-note")
            widened += here
    fig._widened = widened
    return widened


#: Most TQI markers per track (thinned evenly; every change of state is always marked).
MAX_STATE_MARKERS = 40


def tqi_markers(ax: Any, x: ArrayLike, y: ArrayLike, states: ArrayLike, *, color: Any,
                ms: float = 3.0, max_markers: int = MAX_STATE_MARKERS) -> None:
    """Mark each point with its TQI state's marker (:data:`TQI_MARKERS`), in the track's colour.

    Parameters
    ----------
    ax : matplotlib Axes
    x, y : array_like, shape (n,)
        Point coordinates.
    states : array_like of str, shape (n,)
        State labels (``lost``, ``uncertain``, ``low_snr``, ``strong``; others are not marked).
    color : matplotlib colour, keyword-only
        The track's colour (its identity).
    ms : float, keyword-only
        Marker size, points.
    max_markers : int, keyword-only
        Markers per call at most, evenly spaced, plus the first point of every run of a state
        (so that a short spell of ``lost`` or ``uncertain`` is never thinned away).
    """
    x, y, s = np.asarray(x), np.asarray(y), np.asarray(states).astype(str)
    keep = np.zeros(s.size, dtype=bool)
    keep[:: max(1, int(np.ceil(s.size / max(max_markers, 1))))] = True
    keep[1:] |= s[1:] != s[:-1]
    keep[:1] = True
    for state, marker in TQI_MARKERS.items():
        m = (s == state) & keep
        if m.any():
            filled = marker not in ("x", "+")
            ax.plot(x[m], y[m], marker, ms=ms, color=color, ls="none",
                    mfc="none" if state != "strong" and filled else color, gid=f"tqi-{state}")


def state_legend(ax: Any) -> None:
    """Legend entries (black) of the TQI markers, for the figures that draw them."""
    for state, marker in TQI_MARKERS.items():
        ax.plot([], [], marker, color="k", ls="none", ms=4,
                mfc="none" if state != "strong" and marker not in ("x", "+") else "k",
                label=f"TQI {state}")


def covariance_ellipse(ax: Any, centre: Sequence[float], cov: ArrayLike, *, n_sigma: float = 2.0,
                       **patch_kw: Any) -> Any:
    """Draw the ``n_sigma`` ellipse of a 2 x 2 covariance around `centre`.

    Parameters
    ----------
    ax : matplotlib Axes
    centre : (float, float)
        Centre (x, y), in the axes' units.
    cov : array_like, shape (2, 2)
        Covariance, units squared.
    n_sigma : float, keyword-only
        Semi-axes are `n_sigma` standard deviations along the eigenvectors.
    **patch_kw
        Passed to :class:`matplotlib.patches.Ellipse` (default: no fill).

    Returns
    -------
    matplotlib Ellipse
    """
    from matplotlib.patches import Ellipse

    vals, vecs = np.linalg.eigh(np.asarray(cov, dtype=float))
    angle = np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1]))
    width, height = 2.0 * n_sigma * np.sqrt(np.maximum(vals[::-1], 0.0))  # full axes
    patch_kw.setdefault("fill", False)
    patch_kw.setdefault("gid", UNCERTAINTY_GID)  # widened to be seen (ensure_visible)
    patch = Ellipse(tuple(centre), width, height, angle=angle, **patch_kw)
    ax.add_patch(patch)
    return patch
