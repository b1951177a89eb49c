"""Defaults of the click chain that the library and ``fusion localize`` share.

Standard library only: the command line reads them to print ``--help`` before importing the
numerical libraries, and :class:`fusion.pipelines.clicks.ClickFrontEnd` (so
:class:`fusion.pipelines.localization.ClickLocalization` and the demo) builds its default
detector and validator from them, so that a library user and a command-line user detect and
validate alike (``docs/localization.md`` sections 8, 13 and 18).
"""

from __future__ import annotations

__all__ = ["DETECT_FALSE_ALARMS_PER_S", "LLR_THRESHOLD", "SENSOR_POSITION_SIGMA_M",
           "TRAIN_FALSE_ALARMS"]

#: Detection threshold as a noise false-alarm rate (``--detect-false-alarms-per-s``): the click
#: detector's threshold is the level at which it finds this many clicks per channel-second in
#: white Gaussian noise (about 4.9 on the estimated 26-kHz band at 96 kHz, against the fixed
#: 6.0 of a :class:`~fusion.clicks.detect.ClickDetector` built without it, ~0.04 a second);
#: tuned on seeds 0-9 at 15-30 dB.
DETECT_FALSE_ALARMS_PER_S = 0.5

#: Threshold on the log-likelihood ratio at which the shipped validator is used
#: (``--llr-threshold``): just above even odds. The model's own threshold (3.24 for v1, 4.21 for
#: v2, chosen for a low false-alarm rate of the validator alone) drops the short click trains
#: of far sensors whose pairs a fix needs; the candidates' competition, reading echo delays
#: along their paths, rejects most false TDOAs that pass. With ``validator_v2.npz`` surface-echo
#: trains of 8-11 clicks score LLR 0.03-0.4, so the bar is 0.5, not 0.
LLR_THRESHOLD = 0.5

#: False-alarm probability of one (window, pair) search of train integration
#: (``--train-false-alarms-per-pair``, :mod:`fusion.clicks.train_integration`).
TRAIN_FALSE_ALARMS = 1e-3

#: Standard deviation of the array file's sensor positions per axis, m
#: (``--sensor-position-sigma-m``; 0: the positions exact): an assumption of a range survey a
#: few metres good (the simulator's ``--vary-only survey`` draws 1-3 m). The sensors' offsets
#: are estimated from a recording's fixes and used only where they fit them significantly
#: better and explain fixes left out of their fit (``docs/localization.md`` section 24).
SENSOR_POSITION_SIGMA_M = 2.0
