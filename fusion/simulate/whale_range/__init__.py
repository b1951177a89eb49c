"""The world of the whale-click simulator: a bottom-mounted hydrophone range and its physics.

The parts of :func:`fusion.simulate.clicks.simulate_clicks` (``fusion simulate clicks``), one
role per module: the data classes of a scenario (``types``), the range -- sea floor, hydrophone
layout and heights, per-sensor echo coefficients (``world``) -- sound propagation through a
depth-dependent sound-speed profile with surface and floor reflections (``propagation``), the
whales and other species' click trains (``sources``), waveform rendering and band-limited noise
(``synthesis``), the varied assumptions of ``--vary`` and their declared ranges (``varied``),
option checks (``validate``) and the written files (``files``). It uses numpy and
:mod:`fusion.geometry`, :mod:`fusion.io` for the files; nothing of the estimators.
"""

from fusion.simulate.whale_range.files import truth_document, write_click_scenario
from fusion.simulate.whale_range.types import ClickScenario, ClickWaveform, WhaleTrack
from fusion.simulate.whale_range.varied import VARIED_RANGES, varied_settings

__all__ = ["VARIED_RANGES", "ClickScenario", "ClickWaveform", "WhaleTrack", "truth_document",
           "varied_settings", "write_click_scenario"]
