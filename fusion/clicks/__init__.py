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

Multi-source localization of a window's TDOAs (steps 56-62, eq. 14-22):

``window_tdoas``  a window's validated TDOAs with their array, checked once
``surface_paths`` each TDOA read along direct and surface-reflected paths (image sensors)
``search_grid``   the search box and grids, sized by the array
``intensity``     hyperbolic intensity surfaces, eq. (16)-(17) and the weighted eq. (18)
``peak_search``   coarse-to-fine peak refinement and the depth of a fix
``surfaces``      one import path for the four modules above
``candidates``    candidate sources: local maxima of the eq. (18) volume
``ownership``     which TDOAs a candidate holds (eq. 20-21 weights, merging, dropping)
``competition``   candidates competing for the TDOAs, each re-solved on the factor graph (eq. 19-22)
``source_fix``    a localized source with its covariance and the weighted solve behind it
``localize``      the window's multi-source localizer (the stages above in order)
``tracks``        sources linked across windows and smoothed on a factor graph

Support: ``mixture`` (Gaussian mixtures as plain arrays), ``training`` (synthetic SCM2s for the
validator), ``scoring`` (detections against a simulated truth; tests and benchmarks only).
"""
