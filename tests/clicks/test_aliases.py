"""Tests of the one-delay-per-click-train screen (alias TDOAs)."""

from __future__ import annotations

import numpy as np

from fusion.clicks.aliases import train_aliases
from fusion.clicks.window import WindowTdoa

TAU = 0.005  # the train's delay t_i - t_j, s
ICI = 0.5  # its mean inter-click interval, s


def _tdoa(tau: float, times: np.ndarray, *, passes: bool = True, pair=(0, 1)) -> WindowTdoa:
    return WindowTdoa(pair=pair, tau_s=tau, tau_coarse_s=tau, sigma_s=1e-5, crb_s=1e-6,
                      snr_db=30.0, rate=0.0, scm_peak=float(times.size), n_clicks=times.size,
                      features=np.zeros(4), llr=1.0, passes=passes, click_times_s=times,
                      t_s=6.0)


def _train(seed: int = 0) -> np.ndarray:
    """24 click times at sensor i, ICI 0.5 s with 3 % jitter; a few exactly 0.5 s apart."""
    rng = np.random.default_rng(seed)
    ici = ICI * (1.0 + 0.03 * rng.standard_normal(23))
    ici[::3] = ICI
    return 0.2 + np.concatenate([[0.0], np.cumsum(ici)])


def test_one_ici_alias_is_marked_and_the_train_and_others_kept():
    """The train (all its clicks), its alias one click over (sensor i's click n against sensor
    j's click n + 1: only the clicks whose next interval is the mean match, at tau - ICI),
    an echo path (sensor i's clicks against sensor j's echoes 0.31 s later) and another
    whale's train on the same pair: only the alias is marked."""
    t = _train()
    nxt = np.diff(t)
    alias_clicks = t[:-1][np.abs(nxt - ICI) < 1e-4]
    assert 6 <= alias_clicks.size < t.size // 2
    other = _train(seed=1) + 0.137  # another whale: other clicks at sensor i
    tdoas = [_tdoa(TAU, t), _tdoa(TAU - ICI, alias_clicks), _tdoa(TAU - 0.31, t[::2]),
             _tdoa(0.2, other[:10])]
    assert train_aliases(tdoas).tolist() == [False, True, False, False]
    # the weaker one is the alias, whichever comes first; another pair is never compared
    assert train_aliases(tdoas[::-1]).tolist() == [False, False, True, False]
    moved = [tdoas[0], _tdoa(TAU - ICI, alias_clicks, pair=(0, 2))]
    assert not train_aliases(moved).any()


def test_only_tdoas_that_pass_validation_are_compared():
    """An alias of a train that failed validation is kept (there is no stronger delay), and a
    failed alias is not marked again."""
    t = _train()
    alias_clicks = t[:-1][np.abs(np.diff(t) - ICI) < 1e-4]
    assert not train_aliases([_tdoa(TAU, t, passes=False), _tdoa(TAU - ICI, alias_clicks)]).any()
    assert not train_aliases([_tdoa(TAU, t), _tdoa(TAU - ICI, alias_clicks,
                                                    passes=False)]).any()
    assert train_aliases([]).shape == (0,)
