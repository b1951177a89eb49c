"""Multistatic active sonar tracking ("Target tracking using fuzzy logic association").

One module per role, bottom up:

- :mod:`~fusion.active.types`: pings, per-ping tracks, a run (data only);
- :mod:`~fusion.active.fuzzy` and :mod:`~fusion.active.rulebase`: the fuzzy inference engine and
  the paper's rule base as data;
- :mod:`~fusion.active.kalman`: constant-velocity prediction, update, pair statistics, gate;
- :mod:`~fusion.active.bistatic`: a detection's error ellipse and equivalent aspect angle;
- :mod:`~fusion.active.clutter`: the online clutter map (hotspots);
- :mod:`~fusion.active.association`: fuzzy rank of gated pairs, rank threshold, assignment;
- :mod:`~fusion.active.lifecycle`: M-of-N confirmation, deletion, hotspot drop, stationary hold;
- :mod:`~fusion.active.motion`: the motion test (do a track's own detections move?);
- :mod:`~fusion.active.track_score`: the log-likelihood-ratio track score, ``P_D`` and clutter
  intensity learnt per receiver;
- :mod:`~fusion.active.shadow`: returns behind a near confirmed track (radar ghosts);
- :mod:`~fusion.active.ping_scan`: one ping's work state, score gate, new tracks, the result;
- :mod:`~fusion.active.tracker`: the tracker, composed of the above;
- :mod:`~fusion.active.settings` and :mod:`~fusion.active.pilot`: scales read from the
  detections, the speed prior from a pilot run's confirmed tracks;
- :mod:`~fusion.active.smoothing`: confirmed tracks refined on a GTSAM factor graph.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.active import *` imports them all.
__all__ = [
    "association",
    "bistatic",
    "clutter",
    "data",
    "fuzzy",
    "kalman",
    "lifecycle",
    "motion",
    "noise",
    "pilot",
    "ping_scan",
    "platform",
    "rulebase",
    "settings",
    "shadow",
    "smoothing",
    "track_score",
    "tracker",
    "types",
]
