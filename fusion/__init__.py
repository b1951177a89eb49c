"""sonar-fusion: probabilistic sensor fusion for underwater acoustics on factor graphs.

What a user calls is importable from here (listed in ``__all__``) and loaded only when first
used, so ``import fusion`` (and ``fusion --help``) import neither GTSAM nor SciPy::

    import fusion
    table = fusion.read_bearings("bearings.csv")   # track_id,time,bearing_deg
    result = fusion.smooth_bearings(table)         # scales estimated as `fusion smooth` does
    print(result.settings.describe())
    fusion.write_table("smoothed.csv", result.columns())

Entry points taking a table (from the readers, or a mapping of numpy arrays), estimating the
settings not given from the data exactly as the command of the same job does:
:func:`smooth_bearings` (``fusion smooth``), :func:`find_crossings` (``fusion crossings``),
:func:`track_quality` (``fusion tqi``), :func:`track_detections` (``fusion track``).
Angles: files and these entry points use degrees (``*_deg`` columns and options), the smoothers
and geometry below them radians; the smoothers refuse bearings beyond 2 pi
(:func:`check_radians`).

Sub-packages group the pipelines: :mod:`fusion.passive` (narrowband acquisition, bearing
tracking, track quality, crossings, smoothing, target motion analysis), :mod:`fusion.active`
(multistatic active tracking with fuzzy association), :mod:`fusion.simulate` (seeded scenario
generators). :mod:`fusion.io` reads and writes the file formats; :mod:`fusion.geometry` holds
angles, arrays and delays. Custom GTSAM factors live in the separate :mod:`factors` package.
"""

import importlib
import logging
from typing import Any

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: Public name -> module defining it (imported on first use).
_LAZY = {
    # entry points: a table in, the command's estimated settings, results out
    "smooth_bearings": "fusion.pipelines.bearing_smoothing",
    "fit_smoothing": "fusion.pipelines.bearing_smoothing",
    "SmoothingResult": "fusion.pipelines.bearing_smoothing",
    "find_crossings": "fusion.pipelines.bearing_crossings",
    "CrossingsResult": "fusion.pipelines.bearing_crossings",
    "track_quality": "fusion.pipelines.track_quality",
    "track_detections": "fusion.pipelines.active_tracking",
    "TrackOptions": "fusion.pipelines.active_tracking",
    "TrackingRun": "fusion.pipelines.active_tracking",
    "PassivePipeline": "fusion.pipelines.passive",
    # the smoothers themselves (radians, scales given)
    "BearingSmoother": "fusion.passive.smoothing",
    "MultiTrackSmoother": "fusion.passive.smoothing",
    "SmoothedTrack": "fusion.passive.smoothing",
    # files
    **{name: "fusion.io" for name in (
        "Cube", "Table", "read_alerts", "read_amplitudes", "read_array", "read_audio",
        "read_bearings", "read_cube", "read_detections", "read_localization", "read_ownship",
        "read_smoothed", "read_table", "read_tma_bearings", "read_tma_result", "read_tqi",
        "read_tracks", "write_table")},
    # angles
    "check_radians": "fusion.geometry",
    "wrap_angle": "fusion.geometry",
    "wrap_deg": "fusion.geometry",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    """Import a public name's module on first use (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fusion' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
