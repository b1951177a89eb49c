"""Figures of ``fusion`` results (``fusion report``), one module per figure family.

:mod:`~fusion.report.kinds` tells what a result is; :mod:`~fusion.report.build` draws its
figures (:func:`~fusion.report.build.make_report`); the families: :mod:`~fusion.report.acquisition`
(BTR with the acquired line), :mod:`~fusion.report.bearing_time` (tracks, TQI, crossing alerts),
:mod:`~fusion.report.positions` (multistatic tracks over the clutter map, TMA),
:mod:`~fusion.report.localization` (sources, whale tracks, intensity surfaces);
:mod:`~fusion.report.figures` holds the pieces they and the demo share (colour for a track's
identity, marker shape for its TQI state, uncertainty drawn at least a few pixels wide, the index
line); :mod:`~fusion.report.index` writes the folder's ``summary.md``. matplotlib is imported
only when a figure is made (Agg canvas, no pyplot state).
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.report import *` imports them all.
__all__ = [
    "acquisition",
    "bearing_time",
    "build",
    "figures",
    "index",
    "kinds",
    "localization",
    "positions",
]
