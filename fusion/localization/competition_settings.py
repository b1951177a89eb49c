"""Options of the competition of candidate solutions for a window's TDOAs (eq. 19-22).

:class:`CompetitionSettings` is read by :func:`fusion.localization.competition.compete` and by the
ownership rules of :mod:`fusion.localization.ownership` (which TDOAs a candidate holds); it lives
in its own module so that neither of those imports the other's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CompetitionSettings"]


@dataclass(frozen=True)
class CompetitionSettings:
    """Options of :func:`~fusion.localization.competition.compete`.

    Attributes
    ----------
    clutter_fraction : float
        Prior probability that a TDOA is clutter, in (0, 1).
    beta_scale : float
        ``sigma_t`` of eq. (20) in units of the (annealed) TDOA sigma.
    anneal_factor : float
        Ratio of the delay scale between iterations, in (0, 1).
    max_iterations : int
        Iteration limit.
    min_weight : float
        Smallest total weight ``sum_m w_km`` a candidate keeps once annealed (3.5: about four
        TDOAs, one more than the unknowns).
    min_independent : int
        Smallest rank of the incidence of a candidate's TDOAs of weight > 0.5.
    merge_sigmas : float
        Candidates whose predicted delays differ by less than this many sigmas (RMS over the
        TDOAs either holds) merge.
    max_overlap : float
        Candidates sharing more than this fraction of the smaller one's weight merge.
    use_alpha : bool
        Use ``gamma`` of eq. (21) (needs ``alpha``); False: ``gamma_km = beta_m``.
    pair_exclusive : bool
        Cap a candidate's total weight per sensor pair at one.
    solver_iterations : int
        Levenberg-Marquardt iterations per candidate update.
    tol : float
        Convergence: largest weight change, and largest position change in units of
        ``min(sigma) c``.
    min_alpha_link : float
        Association count that links two TDOAs for the growth step (default 3:
        ``1 - exp(-3/4) = 0.53`` in eq. 21).
    gate_sigmas : float
        Residual gate, in TDOA sigmas, of the growth step.
    min_redundant_tdoas : int
        Held TDOAs (weight > 0.5, associated) a candidate needs beyond the three unknowns of
        its position (default 0: off; 1 is the test, off for the reason of section 25). Three
        TDOAs on three independent pairs fit some position exactly, so a fix on three has no
        residual left to test: ``min_weight`` alone let three held TDOAs plus small weights
        on many others pass
        (``docs/localization.md`` section 25).
    echo_ghost_lag_s : float
        Longest bottom-echo lag, s, of the echo-ghost test run on the survivors
        (:func:`fusion.localization.echo_ghosts.echo_ghosts`: a candidate whose delays are
        another's moved by echo lags on at most two sensors is dropped). 0.03 is the longest
        lag the front end takes as an echo (:class:`fusion.clicks.echoes`). Default 0: off
        (with the redundancy test, both off: on three whales they starved the sound-speed
        estimate of fixes, ``docs/localization.md`` section 25).
    polarity_slip_s : float
        Half a carrier period of the lowest click frequency, s (default 25e-6: 20 kHz, the low
        edge of beaked-whale clicks): how far from a surface path's delay the echo-ghost test
        accepts a delay between a click and its sign-inverted surface echo (measured on the
        largest positive correlation, it lands on a side lobe half a period away).
    drop_echo_only_sensors : bool
        With surface paths, drop a survivor that reads some sensor only along its surface echo
        (:func:`fusion.localization.echo_ghosts.echo_only_sensors`). Default False: on
        tuning seed 8003 of ``--vary-only sound-speed`` (array file's speed 0.5 % off) the true
        whale's surface-path fixes read a sensor by its echo alone and were lost.
    """

    clutter_fraction: float = 0.1
    beta_scale: float = 4.0
    anneal_factor: float = 0.3
    max_iterations: int = 40
    min_weight: float = 3.5
    min_independent: int = 3
    merge_sigmas: float = 3.0
    max_overlap: float = 0.5
    use_alpha: bool = True
    pair_exclusive: bool = True
    solver_iterations: int = 10
    tol: float = 1e-2
    min_alpha_link: float = 3.0
    gate_sigmas: float = 3.0
    min_redundant_tdoas: int = 0
    echo_ghost_lag_s: float = 0.0
    polarity_slip_s: float = 25e-6
    drop_echo_only_sensors: bool = False

    def __post_init__(self) -> None:
        for name in ("clutter_fraction", "anneal_factor"):
            v = getattr(self, name)
            if not 0.0 < v < 1.0:
                raise ValueError(f"{name} must lie in (0, 1), got {v!r}")
        for name in ("beta_scale", "merge_sigmas", "tol", "gate_sigmas"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not 0.0 < self.max_overlap <= 1.0:
            raise ValueError(f"max_overlap must lie in (0, 1], got {self.max_overlap!r}")
        if not (np.isfinite(self.min_alpha_link) and self.min_alpha_link >= 0.0):
            raise ValueError(f"min_alpha_link must be >= 0, got {self.min_alpha_link!r}")
        if not self.min_weight >= 0.0:
            raise ValueError(f"min_weight must be >= 0, got {self.min_weight!r}")
        if not (np.isfinite(self.echo_ghost_lag_s) and self.echo_ghost_lag_s >= 0.0):
            raise ValueError(f"echo_ghost_lag_s must be >= 0, got {self.echo_ghost_lag_s!r}")
        if not (np.isfinite(self.polarity_slip_s) and self.polarity_slip_s >= 0.0):
            raise ValueError(f"polarity_slip_s must be >= 0, got {self.polarity_slip_s!r}")
        if int(self.min_redundant_tdoas) != self.min_redundant_tdoas or self.min_redundant_tdoas < 0:
            raise ValueError(f"min_redundant_tdoas must be an integer >= 0, "
                             f"got {self.min_redundant_tdoas!r}")
        for name in ("max_iterations", "min_independent", "solver_iterations"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
