"""Localization of short periodic signals (whale clicks), after *Localization of Short Duration
Periodic Signals* (Baggenstoss, NUWC 102089).

One module per stage, in the order data flows through them:

``replica``  replica correlation (step 36, eq. 1) and the iterative replica estimate (step 32)
``detect``   click detection and screening (steps 38-42, eq. 2)
``scm``      smoothed click maps, their correlation and TDOA peaks (steps 44-48, eq. 3-6), SCM2;
             its results in ``scm_types``
``tdoa``     sub-sample TDOA refinement from the matched click waveforms and the Cramér-Rao bound;
             its result in ``tdoa_types``
``delaytrack`` a pair's delay track through a window: matching along it, robust drift fit
``validate`` TDOA validation: the GMM likelihood ratio (eq. 11) of the SCM2 autocorrelation
             features of ``validate_features`` (eq. 7-10)
``associate`` click-matching association across time (eq. 12) and across sensor pairs (eq. 13)
``event_tdoa`` waveform TDOAs of a detected event (any detector): band, band-passed correlation, closure
``events``   localization of detected events: TDOAs, factor-graph solve, eq. (17) surface check
``types``    the data that flows between them
"""
