"""The parts of the bearing simulator (``fusion simulate bearings``): what
:mod:`fusion.simulate.bearings` draws and records.

``motion``   straight-line relative motions and the rejection sampler of crossing, near-miss,
             parallel and free pairs
``traffic``  manoeuvring vessel traffic around a fixed sensor (``--traffic``)
``varied``   the ranges of a varied scenario (``--vary``)
``truth``    the scenario record and every true crossing of two tracks

It uses numpy and :mod:`fusion.geometry`; the writer and the file formats stay in
:mod:`fusion.simulate.bearings`.
"""

from fusion.simulate.bearing_scene.motion import Builder, Motion, unit
from fusion.simulate.bearing_scene.traffic import TRAFFIC_RANGES, traffic_positions
from fusion.simulate.bearing_scene.truth import BearingScenario, TrueCrossing, find_true_crossings
from fusion.simulate.bearing_scene.varied import VARIED_RANGES, varied_settings

__all__ = [
    "TRAFFIC_RANGES",
    "VARIED_RANGES",
    "BearingScenario",
    "Builder",
    "Motion",
    "TrueCrossing",
    "find_true_crossings",
    "traffic_positions",
    "unit",
    "varied_settings",
]
