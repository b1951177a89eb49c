"""The click front end: from multichannel audio to validated TDOAs of short periodic signals
(whale clicks), after *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089).

This package takes audio samples (an array per channel) and a sensor array and returns, per
processing window, the TDOAs of sensor pairs with their uncertainty, validation score and
association links; localizing sources from them is :mod:`fusion.localization`'s job. It uses
numpy, scipy, :mod:`fusion.geometry`, :mod:`fusion.types` and the shipped models in ``data/``;
nothing of the localization, pipelines or I/O. A user calls :class:`ClickDetector` (with a
:class:`Replica`), :class:`ClickMapCorrelator`, :class:`TdoaRefiner`, :class:`TdoaValidator` and
the association (:class:`TimeAssociator`, :func:`cross_pair_alpha`), or all of them chained by
:class:`fusion.pipelines.clicks.ClickFrontEnd`.

One module per stage, in the order data flows through them:

``replica``  replica correlation (step 36, eq. 1) and the iterative replica estimate (step 32)
``detect``   click detection and screening (steps 38-42, eq. 2)
``echoes``   bottom echoes decided from the data (do the hydrophones stand near the sea floor?)
``scm``      smoothed click maps, their correlation and TDOA peaks (steps 44-48, eq. 3-6), SCM2;
             its results in ``scm_types``
``tdoa``     sub-sample TDOA refinement from the matched click waveforms and the Cramér-Rao bound;
             its result in ``tdoa_types``
``delaytrack`` a pair's delay track through a window: matching along it, robust drift fit
``validate`` TDOA validation: the GMM likelihood ratio (eq. 11) of the SCM2 autocorrelation
             features of ``validate_features`` (eq. 7-10)
``associate`` click-matching association across time (eq. 12) and across sensor pairs (eq. 13)
``types``    the data that flows between them

Support: ``mixture`` (Gaussian mixtures as plain arrays). Private helpers stay inside:
``_click_peaks``, ``_detect_statistic``, ``_frames``, ``_kernels`` (detection), ``_waveform``
(replica), ``_scm2``, ``_scm_grid`` (click maps), ``_tdoa_stats`` (refinement), ``_consensus``
(delay track).

The localization modules that lived here (``localize``, ``tracks``, ``events``, ...) are in
:mod:`fusion.localization`, ``scoring`` is :mod:`fusion.metrics.detections` and ``training``
(synthetic SCM2s, a simulator) is :mod:`fusion.simulate.scm2`; their old import paths here still
work for one release, with a DeprecationWarning.
"""

from fusion.clicks.associate import ClosureCheck, TdoaClicks, TimeAssociator, cross_pair_alpha
from fusion.clicks.detect import ClickDetector
from fusion.clicks.echoes import BottomEchoes, bottom_echoes
from fusion.clicks.replica import Replica, ReplicaEstimate, estimate_replica, load_replica
from fusion.clicks.scm import ClickMapCorrelator, ScmConfig
from fusion.clicks.tdoa import RefinedTdoa, TdoaRefiner
from fusion.clicks.types import ChannelClicks
from fusion.clicks.validate import TdoaValidator

__all__ = [
    "BottomEchoes",
    "ChannelClicks",
    "ClickDetector",
    "ClickMapCorrelator",
    "ClosureCheck",
    "RefinedTdoa",
    "Replica",
    "ReplicaEstimate",
    "ScmConfig",
    "TdoaClicks",
    "TdoaRefiner",
    "TdoaValidator",
    "TimeAssociator",
    "bottom_echoes",
    "cross_pair_alpha",
    "estimate_replica",
    "load_replica",
]
