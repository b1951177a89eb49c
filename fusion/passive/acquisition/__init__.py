"""Acquisition of narrowband targets with high bearing rates: best trace through an IBW BTR.

Implements *Acquisition system particularly suited for tracking targets having high bearing rates*
(US 6,980,486; the project's method text ``acquisition-high-bearing-rate``). An operator clicks a
beam and a frequency on a gram; from the last ``numscans`` normalised beam spectra the method
estimates the target's bearing, bearing rate and SNR to initialise a narrowband tracker. One
module per step:

====  ==========================================================  =================================
step  program segment of the method                               here
====  ==========================================================  =================================
22    normalise each beam spectrum to unit noise mean             :mod:`.normalise`
24    store the beam/frequency/time history                       the :class:`fusion.io.Cube`
26    retrieve the initialisation band (IBW) around the click     :func:`.btr.ibw_bins`
28    BTR: mean over the IBW bins per scan and beam               :func:`.btr.ibw_btr`
40    approximate beamwidth of the clicked beam                   :func:`fusion.geometry.beamwidth_deg`
42    beam tolerance (beams within half a beamwidth, >= 2)        :func:`fusion.geometry.beam_tolerance`
44    anchor beams ``click - tol .. click + tol``                 :mod:`.acquire`
46    best line in a fan (``rateest``, segments 62-70)            :mod:`.fans`: a strategy over
                                                                  :mod:`.traces` (default) or
                                                                  :mod:`.lines` (``trace="beam"``)
48    best line in every other fan                                the same, all fans at once
50    overall best line                                           :meth:`.fans.FanStrategy.search`
52    band noise level, IBW SNR, defaults, SNR in 1 Hz (eq. 4)    :mod:`.snr`
--    sub-beam refinement of the best line (added)                :mod:`.refine`
54    beam -> bearing, beam rate -> bearing rate (eqs. 5-11),     :mod:`fusion.geometry`,
      lag correction                                              :mod:`.acquire`
====  ==========================================================  =================================

The fans' lines are constant-bearing-rate traces by default (:class:`.fans.ConstantRateFans`): the
method's straight lines in beam number, generalised to the cosine beam spacing the method itself
assumes (eqs. 5-11), in which a target at a constant bearing rate draws a curve; each trace is read
at the nearest beam, as ``rateest`` reads its lines. ``trace="beam"``
(:class:`.fans.StraightLineFans`) keeps the literal straight lines. Where the text is silent or
garbled the choices are documented on :class:`Acquisition` and in the step modules.

Around the method, for a tracker that starts from acquisitions: :mod:`.starts`
(:class:`LineStarter`, automatic starts on the strongest lines no track holds) and :mod:`.prior`
(:class:`AcquisitionPrior`, the Gaussian prior of a track's first state from an acquisition's own
SNR, beamwidth and trace length; uses :class:`fusion.passive.smoothing.TrackPrior`).
"""

from fusion.geometry import beamwidth_deg
from fusion.passive.acquisition.acquire import Acquisition, AcquisitionResult, acquire
from fusion.passive.acquisition.btr import ibw_bins, ibw_btr
from fusion.passive.acquisition.fans import (
    BestLine,
    ConstantRateFans,
    FanStrategy,
    StraightLineFans,
)
from fusion.passive.acquisition.lines import FanSearch, best_lines_in_fans, slope_grid
from fusion.passive.acquisition.normalise import (
    expected_median_fraction,
    noise_mean_level,
    normalize_spectra,
)
from fusion.passive.acquisition.prior import AcquisitionPrior
from fusion.passive.acquisition.refine import (
    MATCHED_STEP_BEAMS,
    RefinedTrace,
    matched_trace_score,
    refine_trace,
)
from fusion.passive.acquisition.snr import HAMMING_ENBW, band_noise_level, snr_1hz_db
from fusion.passive.acquisition.starts import LineStarter, StartCandidate
from fusion.passive.acquisition.traces import (
    TraceFanSearch,
    best_traces_in_fans,
    constant_rate_traces,
)

__all__ = [
    "HAMMING_ENBW",
    "MATCHED_STEP_BEAMS",
    "Acquisition",
    "AcquisitionPrior",
    "AcquisitionResult",
    "BestLine",
    "ConstantRateFans",
    "FanSearch",
    "FanStrategy",
    "LineStarter",
    "RefinedTrace",
    "StartCandidate",
    "StraightLineFans",
    "TraceFanSearch",
    "acquire",
    "band_noise_level",
    "beamwidth_deg",
    "best_lines_in_fans",
    "best_traces_in_fans",
    "constant_rate_traces",
    "expected_median_fraction",
    "ibw_bins",
    "ibw_btr",
    "matched_trace_score",
    "noise_mean_level",
    "normalize_spectra",
    "refine_trace",
    "slope_grid",
    "snr_1hz_db",
]
