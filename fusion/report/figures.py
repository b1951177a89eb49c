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
    "TQI_COLOURS",
    "FigureWriter",
    "bearing_band",
    "covariance_ellipse",
    "new_figure",
    "no_wrap_line",
]

logger = logging.getLogger(__name__)

#: Colour of each track-quality state.
TQI_COLOURS: dict[str, str] = {"lost": "0.5", "uncertain": "tab:orange", "low_snr": "tab:blue",
                               "strong": "tab:green"}

#: Dots per inch of the PNG files.
DPI = 100


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

    def save(self, fig: Any, name: str) -> Path:
        """Write `fig` as ``out_dir/name`` (a ``.png`` name); return its path.

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
        with atomic_output(path, suffix=".png") as tmp:
            fig.savefig(tmp, format="png", dpi=DPI)
        self.written.append(path)
        logger.info("wrote %s", path)
        return path


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
    ax.fill_betweenx(t, b - s, b + s, color=line.get_color(), alpha=0.3, lw=0)
    return line


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
    patch = Ellipse(tuple(centre), width, height, angle=angle, **patch_kw)
    ax.add_patch(patch)
    return patch
