"""Delays of a far sensor recruited to teach a recording's sound speed.

A fix from four sensors is exactly determined at any speed: its six delays hold three
independent ones for three coordinates, so it says nothing about the speed, and a speed 0.3-0.5 %
off moves it 10-20 m in depth (seeds 7703, 7800, 7803 of ``--vary-only sound-speed``, one whale,
5 sensors: every window solved from four sensors, the fifth one's pairs too sparse to pass the
validator). When a recording has too few fixes spanning five sensors
(:data:`fusion.localization.sound_speed.MIN_CALIBRATION_FIXES`), the fifth sensor's candidate
delays -- those the validator left below its bar, never used for a fix -- can still tell the
speed by consensus: for each such candidate of a pair joining a fix's four sensors to the
missing one, :func:`candidate_speeds` finds the speed at which the fix (re-solved from its own
four sensors) predicts it. A chance candidate implies a chance speed; the true ones of different
windows imply the same speed. :func:`recruit` keeps the speed most windows agree on (within
:data:`AGREE_MPS`, at least :data:`MIN_WINDOWS` windows) and appends to each agreeing fix its
candidate nearest to that speed, so the recording's graph
(:func:`fusion.localization.sound_speed.estimate_sound_speed`) is solved with them and its own
checks (sigma, change from the file's value) decide. The recruited delays teach the speed only:
every fix is re-solved at the estimate from the delays it owns.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.localization.sound_speed import FixTdoas, refit_fix

__all__ = ["AGREE_MPS", "MIN_WINDOWS", "candidate_speeds", "recruit"]

#: Speeds of two candidates closer than this agree, m/s (set once on seeds 7700-7709 and
#: 7800-7809, not tuned further).
AGREE_MPS = 0.75
#: Fewest windows whose candidates must agree on one speed.
MIN_WINDOWS = 3
#: Speeds tried around the file's value: +-SPAN (relative), in STEPS steps.
SPAN = 0.015
STEPS = 13


def candidate_speeds(fix: FixTdoas, cand: FixTdoas, nominal_mps: float
                     ) -> NDArray[np.float64]:
    """For each delay of `cand` (on the same sensors as `fix`), the speed at which `fix`
    re-solved from its own delays predicts it (NaN where no speed within +-SPAN does), m/s."""
    grid = nominal_mps * np.linspace(1.0 - SPAN, 1.0 + SPAN, STEPS)
    s = cand.sensors
    resid = np.empty((STEPS, cand.m))
    for k, c in enumerate(grid):
        p, _ = refit_fix(fix, float(c))
        pred = (np.linalg.norm(p - s[cand.pairs[:, 0]], axis=1)
                - np.linalg.norm(p - s[cand.pairs[:, 1]], axis=1)) / c
        resid[k] = pred - cand.taus
    out = np.full(cand.m, np.nan)
    for j in range(cand.m):
        r = resid[:, j]
        cross = np.nonzero(np.sign(r[:-1]) * np.sign(r[1:]) <= 0)[0]
        if cross.size == 1:  # one crossing: interpolate; several: ambiguous
            k = int(cross[0])
            w = r[k] / (r[k] - r[k + 1]) if r[k] != r[k + 1] else 0.0
            out[j] = grid[k] + w * (grid[k + 1] - grid[k])
    return out


def recruit(fixes: list[tuple[int, FixTdoas, FixTdoas]], nominal_mps: float
            ) -> tuple[list[FixTdoas], float | None]:
    """The fixes with the candidate delays that agree on one speed appended.

    Parameters
    ----------
    fixes : list of (window index, fix, candidates)
        Each four-sensor fix with the candidate delays of its window's pairs to a sensor it
        does not use (on the fix's sensors, moved to its emission).
    nominal_mps : float
        The array file's speed, m/s.

    Returns
    -------
    (fixes, speed)
        The fixes of the windows that agree, each with its agreeing candidates appended, and
        the speed they agree on (None and an empty list when fewer than :data:`MIN_WINDOWS`
        windows agree).
    """
    rows = []  # (window, fix number, candidate number, speed)
    for n, (w, fix, cand) in enumerate(fixes):
        for j, c in enumerate(candidate_speeds(fix, cand, nominal_mps)):
            if np.isfinite(c):
                rows.append((w, n, j, float(c)))
    if not rows:
        return [], None
    speeds = np.array([r[3] for r in rows])
    windows = np.array([r[0] for r in rows])
    support = [np.unique(windows[np.abs(speeds - c) <= AGREE_MPS]).size for c in speeds]
    best = int(np.argmax(support))
    if support[best] < MIN_WINDOWS:
        return [], None
    near = np.abs(speeds - speeds[best]) <= AGREE_MPS
    c_star = float(np.median(speeds[near]))
    out = []
    for n, (_, fix, cand) in enumerate(fixes):
        picked: dict[tuple[int, int], int] = {}  # one candidate per pair: the nearest
        for (_, m, j, c), ok in zip(rows, near, strict=True):
            if m != n or not ok:
                continue
            key = tuple(cand.pairs[j])
            if key not in picked or abs(c - c_star) < abs(picked_speed(rows, n, picked[key])
                                                         - c_star):
                picked[key] = j
        if not picked:
            continue
        j = np.array(sorted(picked.values()))
        out.append(FixTdoas(fix.sensors, np.vstack([fix.pairs, cand.pairs[j]]),
                            np.concatenate([fix.taus, cand.taus[j]]),
                            np.concatenate([fix.sigmas, cand.sigmas[j]]),
                            np.concatenate([fix.weights, cand.weights[j]]), fix.position))
    return out, c_star


def picked_speed(rows: list[tuple[int, int, int, float]], n: int, j: int) -> float:
    """The speed of candidate `j` of fix `n` in `rows`."""
    return next(r[3] for r in rows if r[1] == n and r[2] == j)
