"""Localization: from the validated TDOAs of processing windows to sources and their tracks
(steps 56-62 of *Localization of Short Duration Periodic Signals*, eq. 14-22).

This package takes a window's TDOAs with their sensor array (:class:`WindowTdoas`, built from the
click front end's output of :mod:`fusion.clicks` or from any TDOA source) and returns the
window's sources with covariances (:class:`SourceFix`) and tracks across windows
(:class:`Track`); it also localizes events another detector found (:class:`EventLocalizer`). It
uses numpy, scipy, GTSAM through :mod:`factors` (TDOA and motion factors), :mod:`fusion.geometry`
and :mod:`fusion.types`; nothing of :mod:`fusion.clicks`, the pipelines or I/O. A user calls
:class:`MultiSourceLocalizer` per window and :class:`SourceTracker` across windows, or both
chained by :mod:`fusion.pipelines.localization`.

One module per role, in the order data flows through them:

``window_tdoas``  a window's validated TDOAs with their array, checked once
``surface_paths`` each TDOA read along direct and surface-reflected paths (image sensors)
``search_grid``   the search box and grids, sized by the array
``intensity``     hyperbolic intensity surfaces, eq. (16)-(17) and the weighted eq. (18)
``peak_search``   coarse-to-fine peak refinement and the depth of a fix
``surfaces``      one import path for the four modules above
``candidates``    candidate sources: local maxima of the eq. (18) volume
``ownership``     which TDOAs a candidate holds (eq. 20-21 weights, merging, dropping)
``competition_settings`` the options of the competition (shared by ``ownership`` and ``competition``)
``competition``   candidates competing for the TDOAs, each re-solved on the factor graph (eq. 19-22)
``source_fix``    a localized source with its covariance and the weighted solve behind it
``localize``      the window's multi-source localizer (the stages above in order)
``whale_settings`` the localizer for whale clicks below the sea surface and ``fusion localize``'s
                  array-independent localization settings
``tracks``        sources linked across windows and smoothed on a factor graph
``event_tdoa``    waveform TDOAs of a detected event (any detector): band, band-passed correlation,
                  closure
``events``        localization of detected events: TDOAs, factor-graph solve, eq. (17) surface check
"""

from fusion.localization.candidates import CandidateFinder
from fusion.localization.competition import CompetitionSettings, compete
from fusion.localization.events import Event, EventFix, EventLocalizer
from fusion.localization.localize import METHODS, LocalizationOutput, MultiSourceLocalizer
from fusion.localization.search_grid import SearchGrid, SearchRegion
from fusion.localization.source_fix import SourceFix
from fusion.localization.surface_paths import surface_paths
from fusion.localization.surfaces import intensity_volume
from fusion.localization.tracks import SourceTracker, Track, WindowSources
from fusion.localization.window_tdoas import WindowTdoas

__all__ = [
    "METHODS",
    "CandidateFinder",
    "CompetitionSettings",
    "Event",
    "EventFix",
    "EventLocalizer",
    "LocalizationOutput",
    "MultiSourceLocalizer",
    "SearchGrid",
    "SearchRegion",
    "SourceFix",
    "SourceTracker",
    "Track",
    "WindowSources",
    "WindowTdoas",
    "compete",
    "intensity_volume",
    "surface_paths",
]
