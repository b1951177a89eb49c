"""The passive narrowband chain as one pipeline: acquisition, fixed-lag graphs, TQI, crossings.

This package chains the passive stages on beam/frequency/time scans (:class:`fusion.types.Cube`):
it measures each live track in each scan, updates its track quality
(:mod:`fusion.passive.quality`), keeps its (bearing, bearing rate) on a GTSAM fixed-lag graph
(:mod:`factors`), runs the crossing detector (:mod:`fusion.passive.crossing`) and resolves
crossing episodes with the multi-track smoother (:mod:`fusion.passive.smoothing`); tracks start
from operator clicks or automatically, through :mod:`fusion.passive.acquisition`. It holds no
algorithm of its own and imports no I/O. A user builds a :class:`PassivePipeline` and calls
``run(cubes, clicks)`` for whole cubes or ``step(scan)`` for streaming, and reads a
:class:`PassiveResult`.

Modules: the parts are
:mod:`~fusion.pipelines.passive.pipeline` (the pipeline), :mod:`~fusion.pipelines.passive.crossing`
(crossing episodes), :mod:`~fusion.pipelines.passive.types` (scans and clicks in, results
out) and :mod:`~fusion.pipelines.passive.noise` (the cubes on the unit-noise scale the tracker
reads, normalised where their noise level says so: :func:`unit_noise_cubes`). The algorithms
it calls live in their stages: the peak measurement in
:mod:`fusion.passive.measurement`, automatic starts and the acquisition prior in
:mod:`fusion.passive.acquisition` (:class:`LineStarter` is re-exported here, as the pipeline's
``starter``), the fixed-lag graph of one track in :mod:`fusion.passive.smoothing.fixed_lag`.
"""

from fusion.passive.acquisition.starts import LineStarter
from fusion.pipelines.passive.noise import unit_noise_cubes
from fusion.pipelines.passive.pipeline import PassivePipeline
from fusion.pipelines.passive.types import (
    Click,
    PassiveResult,
    PassiveTrack,
    Scan,
    ScanResult,
    SmootherSettings,
    TrackEnd,
    TrackStart,
    TrackUpdate,
    scans_of,
)

__all__ = [
    "Click",
    "LineStarter",
    "PassivePipeline",
    "PassiveResult",
    "PassiveTrack",
    "Scan",
    "ScanResult",
    "SmootherSettings",
    "TrackEnd",
    "TrackStart",
    "TrackUpdate",
    "scans_of",
    "unit_noise_cubes",
]
