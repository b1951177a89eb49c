"""Training the TDOA validator (and the replica) from labelled recordings or simulated scenarios.

The validator of *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089,
step 50, eq. 7-11) is a likelihood ratio of two Gaussian mixtures over SCM2 features, trained on
experimental data. Here the training data are the front end's own candidate TDOAs
(:class:`fusion.pipelines.clicks.ClickFrontEnd` run without a validator), each labelled valid
when it lies within a tolerance of a labelled TDOA of the same sensor pair, interpolated to the
candidate's reference time (the window centre), and invalid otherwise: inter-click-interval
aliases, direct-echo and cross-whale coincidences, transients.

Labels (``time,i,j,tau`` and optionally ``source``) are one row per labelled click: the arrival
time at sensor ``i`` (s from the start of the audio) and the TDOA ``t_i - t_j`` (s) of that click.
With a ``source`` column the TDOA of each source is interpolated in time; without it the nearest
labelled click in time is used. ``fusion simulate clicks`` writes such a file
(``tdoa_labels.csv``) from its ground truth; an analyst writes one from manual picks.

The shipped model (``fusion/clicks/data/validator_v2.npz``; ``validator_v1.npz`` before issue 17's
ICI range) comes from
:func:`simulated_training_set` over the tuning seeds named in
``benchmarks/bench_click_frontend.py``, with the simulator's assumptions varied
(:func:`varied_scenario`).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.validate import TdoaValidator, train_validator
from fusion.pipelines.clicks.frontend import ClickFrontEnd, ClickWindow

__all__ = [
    "CandidateSet",
    "TdoaLabels",
    "label_windows",
    "scenario_labels",
    "simulated_training_set",
    "train_from_candidates",
    "varied_scenario",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class TdoaLabels:
    """Labelled TDOAs, one row per click.

    Attributes
    ----------
    time_s : ndarray, shape (n,)
        Arrival time at sensor ``i``, s.
    i, j : ndarray of int, shape (n,)
        Sensor indices.
    tau_s : ndarray, shape (n,)
        ``t_i - t_j``, s.
    source : ndarray of int, shape (n,)
        Source of each click (-1: unknown).
    """

    time_s: NDArray[np.float64]
    i: NDArray[np.int64]
    j: NDArray[np.int64]
    tau_s: NDArray[np.float64]
    source: NDArray[np.int64]

    @classmethod
    def from_columns(cls, columns: dict) -> TdoaLabels:
        """From named columns ``time,i,j,tau[,source]`` (e.g. a :class:`fusion.io.Table`)."""
        n = len(np.asarray(columns["time"]))
        src = np.asarray(columns["source"], int) if "source" in columns else np.full(n, -1)
        i, j = np.asarray(columns["i"], int), np.asarray(columns["j"], int)
        if np.any(i == j) or np.any(i < 0) or np.any(j < 0):
            raise ValueError("labels: i and j must be two different non-negative sensor indices")
        return cls(np.asarray(columns["time"], float), i, j, np.asarray(columns["tau"], float),
                   src)

    def tau_at(self, pair: tuple[int, int], t_s: float, t0_s: float, t1_s: float) -> NDArray:
        """Labelled TDOAs of `pair` at time `t_s` (one per source seen in ``[t0_s, t1_s)``)."""
        a, b = pair
        fwd = (self.i == a) & (self.j == b)
        rev = (self.i == b) & (self.j == a)
        sel = (fwd | rev) & (self.time_s >= t0_s) & (self.time_s < t1_s)
        if not np.any(sel):
            return np.empty(0)
        t = self.time_s[sel]
        tau = np.where(fwd[sel], self.tau_s[sel], -self.tau_s[sel])
        # a reversed row's time is at sensor j: move it to sensor i's clock
        t = np.where(fwd[sel], t, t + tau)
        src = self.source[sel]
        out = []
        for s in np.unique(src):
            k = src == s
            if s < 0:
                out.append(tau[k][np.argmin(np.abs(t[k] - t_s))])
            else:
                order = np.argsort(t[k])
                out.append(np.interp(t_s, t[k][order], tau[k][order]))
        return np.asarray(out)


def scenario_labels(scenario) -> TdoaLabels:
    """Direct-path TDOA labels of every click and pair of a simulated scenario.

    Parameters
    ----------
    scenario : fusion.simulate.clicks.ClickScenario

    Returns
    -------
    TdoaLabels
    """
    rows = []
    for src in scenario.sources:
        arr = src.arrival_times
        for i, j in scenario.pairs():
            rows.append((arr[:, i], np.full(arr.shape[0], i), np.full(arr.shape[0], j),
                         arr[:, i] - arr[:, j], np.full(arr.shape[0], src.source_id)))
    cols = [np.concatenate(c) for c in zip(*rows, strict=True)]
    return TdoaLabels(cols[0], cols[1].astype(int), cols[2].astype(int), cols[3],
                      cols[4].astype(int))


def label_windows(
    windows: Sequence[ClickWindow], labels: TdoaLabels, *, tol_s: float = 3e-3,
    coarse: bool = False,
) -> list[NDArray[np.bool_]]:
    """Label each window's candidate TDOAs: within `tol_s` of a labelled TDOA of its pair.

    The labelled TDOA is taken at the window centre (the reference time of the refined TDOA).
    ``coarse=True`` labels the SCM peak (``tau_coarse_s``) instead of the refined TDOA. The
    default tolerance, 3 ms, is about the half-width of the SCM pulse: the coarse delay of a
    moving source lies within it, while inter-click-interval aliases (>= 0.2 s away) and
    coincidences do not.
    """
    out = []
    for w in windows:
        mid = 0.5 * (w.t_start + w.t_end)
        y = np.zeros(len(w.tdoas), dtype=bool)
        for k, d in enumerate(w.tdoas):
            ref = labels.tau_at(d.pair, mid, w.t_start, w.t_end)
            tau = d.tau_coarse_s if coarse else d.tau_s
            y[k] = bool(ref.size and np.min(np.abs(ref - tau)) < tol_s)
        out.append(y)
    return out


@dataclass(frozen=True)
class CandidateSet:
    """Features of labelled candidate TDOAs.

    Attributes
    ----------
    z : ndarray, shape (n, 4)
        SCM2 features (eq. 10).
    valid : ndarray of bool, shape (n,)
        Label.
    seed : ndarray of int, shape (n,)
        Scenario (or recording) each row comes from.
    """

    z: NDArray[np.float64]
    valid: NDArray[np.bool_]
    seed: NDArray[np.int64]


def varied_scenario(seed: int, *, duration_s: float = 30.0):
    """A click scenario whose physical assumptions are drawn from documented ranges.

    Ranges: 1-3 whales, 3-8 sensors, SNR at the reference range 12-36 dB, mean ICI over the
    varied range's ``ici_range_s`` (0.2-1.0 s, :data:`fusion.simulate.whale_range.varied.
    VARIED_RANGES`) with 0-20 % jitter, surface reflection coefficient -0.95 to 0 (none), 0-20
    transients, array radius 1-2 km, source level jitter 1-4 dB. The draw uses its own
    generator seeded by `seed`; the scenario itself is simulated with the same seed.
    (``validator_v1.npz`` was trained with mean ICIs of 0.25-0.6 s only: it rejects the clean
    trains of a whale clicking once a second, ``docs/localization.md`` section 11.)
    """
    from fusion.simulate.clicks import simulate_clicks
    from fusion.simulate.whale_range.varied import VARIED_RANGES

    rng = np.random.default_rng([seed, 77])
    ici = float(rng.uniform(*VARIED_RANGES["ici_range_s"]))
    return simulate_clicks(
        seed=seed, duration_s=duration_s, n_sources=int(rng.integers(1, 4)),
        n_sensors=int(rng.integers(3, 9)), snr_db=float(rng.uniform(12.0, 36.0)),
        ici_s=ici, ici_jitter_s=float(rng.uniform(0.0, 0.2)) * ici,
        surface_reflection=float(rng.uniform(-0.95, 0.0)),
        n_transients=int(rng.integers(0, 21)), array_radius_m=float(rng.uniform(1000, 2000)),
        level_jitter_db=float(rng.uniform(1.0, 4.0)),
    )


def simulated_training_set(
    seeds: Iterable[int], *, duration_s: float = 30.0, tol_s: float = 3e-3,
    front_end: ClickFrontEnd | None = None,
) -> CandidateSet:
    """Run the front end (without validation) on varied simulated scenarios and label it."""
    fe = front_end if front_end is not None else ClickFrontEnd(validator=False, refiner=False)
    zs, ys, ss = [], [], []
    for seed in seeds:
        sc = varied_scenario(int(seed), duration_s=duration_s)
        windows = fe.run_array(sc.audio, sc.fs, sc.sensors)
        labels = label_windows(windows, scenario_labels(sc), tol_s=tol_s)
        for w, y in zip(windows, labels, strict=True):
            if w.tdoas:
                zs.append(np.stack([d.features for d in w.tdoas]))
                ys.append(y)
                ss.append(np.full(y.size, int(seed)))
        logger.info("seed %d: %d candidates", seed, sum(len(w.tdoas) for w in windows))
    if not zs:
        raise ValueError("no candidate TDOAs in the training scenarios")
    return CandidateSet(np.concatenate(zs), np.concatenate(ys), np.concatenate(ss))


def train_from_candidates(
    data: CandidateSet, *, n_components: int | None = None, seed: int = 0,
    target_far: float = 0.02,
) -> TdoaValidator:
    """Fit the validator's two mixtures (valid / invalid candidates) and its threshold."""
    if data.valid.sum() < 10 or (~data.valid).sum() < 10:
        raise ValueError(f"training needs >= 10 valid and >= 10 invalid candidates, got "
                         f"{int(data.valid.sum())} and {int((~data.valid).sum())}")
    return train_validator(data.z[data.valid], data.z[~data.valid], n_components=n_components,
                           seed=seed, threshold_rule="far", target_far=target_far)
