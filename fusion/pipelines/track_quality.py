"""Track quality of tracker outputs: ``fusion tqi`` as a library call.

:func:`track_quality` takes the rows of an amplitudes file (a :class:`fusion.types.Table` from
:func:`fusion.io.read_amplitudes`, or a mapping of arrays ``track_id``, ``time``, ``amplitude``
(cell power, linear, noise mean 1) and ``residual`` (bearing error, deg)), runs the track quality
indicator with hysteresis (:class:`fusion.passive.quality.TrackQualityIndicator`) on every track
at once and returns the command's output columns: the input columns plus ``tqi`` (``lost``,
``uncertain``, ``low_snr``, ``strong``). ``fusion tqi`` reading a whole file calls
:func:`quality_columns`, and its chunked path gives the same bytes. The indicator's settings
are the method's defaults (the command's); nothing here is estimated from the data.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.passive.quality import TrackQualityIndicator

__all__ = [
    "DIAGNOSTICS",
    "INPUT_COLUMNS",
    "quality_columns",
    "track_quality",
    "update_grid",
]

#: Input columns, copied to the output.
INPUT_COLUMNS = ("track_id", "time", "amplitude", "residual")
#: Diagnostic output column -> :class:`~fusion.passive.quality.TQIMemory` field.
DIAGNOSTICS = {"sllr0": "sllr0", "sllr1": "sllr1", "smoothed_residual": "residual_deg",
               "err_max": "err_max_deg"}


def update_grid(table: Mapping[str, Any] | Any) -> tuple[np.ndarray, ...]:
    """Rows laid out as (update, track): the k-th row of a track is its k-th update.

    Returns ``tracks`` (sorted ids), ``row_k`` and ``col`` (each row's update and track index)
    and the ``amp``, ``res`` and ``valid`` grids of shape (most updates of a track, tracks).
    Rows of a track must be in time order (checked by the readers).
    """
    tracks, col = np.unique(np.asarray(table["track_id"]), return_inverse=True)
    n = col.size
    order = np.argsort(col, kind="stable")
    counts = np.bincount(col, minlength=tracks.size)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    row_k = np.empty(n, dtype=np.int64)
    row_k[order] = np.arange(n) - np.repeat(starts, counts)
    shape = (int(counts.max()) if n else 0, tracks.size)
    amp = np.full(shape, np.nan)
    res = np.full(shape, np.nan)
    valid = np.zeros(shape, dtype=bool)
    amp[row_k, col] = table["amplitude"]
    res[row_k, col] = table["residual"]
    valid[row_k, col] = True
    return tracks, row_k, col, amp, res, valid


def quality_columns(table: Mapping[str, Any] | Any, indicator: TrackQualityIndicator, *,
                    diagnostics: bool = False) -> dict[str, NDArray[Any]]:
    """The output columns of ``fusion tqi`` for a whole table, in the table's row order."""
    tracks, row_k, col, amp, res, valid = update_grid(table)
    hist = indicator.run(amp, res, valid=valid)
    columns = {name: np.asarray(table[name]) for name in INPUT_COLUMNS}
    columns["tqi"] = hist.labels()[row_k, col]
    if diagnostics:
        for name, field in DIAGNOSTICS.items():
            columns[name] = getattr(hist, field)[row_k, col]
    return columns


def track_quality(table: Mapping[str, Any] | Any, *, diagnostics: bool = False,
                  sllr0_max: float | None = None, **options: Any) -> dict[str, NDArray[Any]]:
    """Track quality of every row of a tracker-output table, as ``fusion tqi`` computes it.

    Parameters
    ----------
    table : Table or mapping
        Columns ``track_id``, ``time`` (s), ``amplitude`` (linear power, noise mean 1),
        ``residual`` (deg); each track's rows in time order.
    diagnostics : bool, keyword-only
        Also return ``sllr0``, ``sllr1``, ``smoothed_residual`` (deg), ``err_max`` (deg).
    sllr0_max : float, keyword-only
        Ceiling of SLLR_0 (``--sllr0-max``; default: the indicator's).
    **options
        Keywords of :class:`~fusion.passive.quality.TrackQualityIndicator` (``snr0_db``,
        ``snr1_db``, ``n_looks``, ``tl``, ``tu``, ``ts``, ``lh``, ``sh``, ``hysteresis``,
        ``omega``, ``t_err``, ``residual_smoothing``); the command's defaults otherwise.

    Returns
    -------
    dict of str to ndarray
        The input columns plus ``tqi`` (labels), and the diagnostics if asked for.
    """
    if sllr0_max is not None:
        defaults = TrackQualityIndicator.__init__.__kwdefaults__ or {}
        tl, lh = options.get("tl", defaults["tl"]), options.get("lh", defaults["lh"])
        options["sllr0_limits"] = (tl - lh, sllr0_max)
    return quality_columns(table, TrackQualityIndicator(**options), diagnostics=diagnostics)
