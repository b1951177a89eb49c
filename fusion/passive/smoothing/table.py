"""Smoothing the rows of a bearing table: labelled tracks alone, unknown-origin rows jointly.

The entry point of ``fusion smooth``: rows with a track id go to a :class:`~fusion.passive.
smoothing.batch.BearingSmoother` track by track, rows of unknown origin (track id -1) to a
:class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from fusion._progress import RowShare
from fusion.passive.smoothing.batch import BearingSmoother
from fusion.passive.smoothing.merge import merge_scan_detections
from fusion.passive.smoothing.multitrack import MultiTrackSmoother
from fusion.passive.smoothing.twins import twin_groups
from fusion.passive.smoothing.types import SmoothedTrack

__all__ = ["smooth_bearings"]


def smooth_bearings(
    track_id: ArrayLike,
    times: ArrayLike,
    bearings: ArrayLike,
    *,
    single: BearingSmoother,
    multi: MultiTrackSmoother,
    merge_within: float = 0.0,
    twin_within: float = 0.0,
    on_rows: Callable[[int], None] | None = None,
) -> tuple[SmoothedTrack, ...]:
    """Smooth a bearing file's rows: labelled tracks alone, unknown-origin rows jointly.

    Parameters
    ----------
    track_id : array_like of int, shape (n,)
        Track of each row; ``-1`` marks a detection of unknown origin.
    times : array_like, shape (n,)
        Times, s (any order).
    bearings : array_like, shape (n,)
        Bearings, rad.
    single : BearingSmoother
        Smoother of each labelled track (``track_id >= 0``).
    multi : MultiTrackSmoother
        Tracker-smoother of the unknown-origin rows; its tracks are numbered after the
        largest labelled id.
    merge_within : float, keyword-only
        Unknown-origin bearings of one scan closer than this are merged first, rad
        (:func:`~fusion.passive.smoothing.merge.merge_scan_detections`; 0: none).
    twin_within : float, keyword-only
        Tracks formed from unknown-origin rows that stay this close to each other over most
        of their common time are one source (:func:`~fusion.passive.smoothing.twins.
        twin_groups`): their detections are smoothed together by `single` (Gaussian loss
        replaced by its robust one), rad (0: none).
    on_rows : callable, keyword-only
        ``on_rows(n)`` as the work goes on, with the rows it covered (each row once, in
        parts: a labelled track's over its solver's iterations and marginals, the
        unknown-origin rows' over the tracker's scans and the tracks formed): a progress
        bar's ``update``. None: not called.

    Returns
    -------
    tuple of SmoothedTrack
        Labelled tracks first (by id), then the tracks formed from unknown-origin rows.
    """
    ids = np.asarray(track_id)
    t = np.asarray(times, float)
    z = np.asarray(bearings, float)
    if not (ids.shape == t.shape == z.shape and ids.ndim == 1):
        raise ValueError("track_id, times and bearings must be 1-D of equal length")
    out: list[SmoothedTrack] = []
    for tid in np.unique(ids[ids >= 0]):
        sel = np.flatnonzero(ids == tid)
        sel = sel[np.argsort(t[sel], kind="stable")]
        out.append(single.smooth(t[sel], z[sel], track_id=int(tid), on_rows=on_rows))
    unk = np.flatnonzero(ids < 0)
    if unk.size:
        unk = unk[np.argsort(t[unk], kind="stable")]
        offset = int(ids.max()) + 1 if (ids >= 0).any() else 0
        tu, zu = t[unk], z[unk]
        if merge_within > 0:
            tu, zu, _ = merge_scan_detections(tu, zu, within=merge_within)
        share = RowShare(unk.size, on_rows)
        res = multi.run(tu, zu, on_progress=None if on_rows is None else share.upto)
        groups = (twin_groups(res.tracks, within=twin_within) if twin_within > 0
                  else [[k] for k in range(len(res.tracks))])
        for new_id, group in enumerate(groups):
            if len(group) == 1:
                tr = res.tracks[group[0]]
            else:  # twins: one source, its detections smoothed as one track
                own = np.flatnonzero(np.isin(res.labels, [res.tracks[k].track_id for k in group]))
                tr = single.smooth(tu[own], zu[own], track_id=new_id)
            out.append(SmoothedTrack(new_id + offset, tr.times, tr.bearing, tr.rate,
                                     tr.sigma_bearing, tr.sigma_rate))
        share.rest()
    return tuple(out)
