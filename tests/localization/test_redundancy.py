"""The redundancy rule of the drop test: a source needs a TDOA beyond its three unknowns."""

from __future__ import annotations

import numpy as np
import pytest

from factors.tdoa import predicted_tdoas, solve_source
from fusion.localization.competition import CompetitionSettings, holds_a_source
from fusion.localization.localize import MultiSourceLocalizer
from fusion.localization.whale_settings import LocalizerSettings, whale_localizer
from fusion.simulate.tdoa_sets import all_pairs

SENSORS = np.array([[0.0, 0, -1000], [1500, 0, -1020], [0, 1500, -990], [1500, 1500, -1010],
                    [750, 750, -1005]])


def three_held_and_crumbs():
    """Three TDOAs held (weight 1) on three independent pairs, 0.1 on eight others: weight
    3.8 >= 3.5 on three TDOAs of weight > 0.5."""
    pairs = all_pairs(5)
    w = np.full(len(pairs), 0.1)
    w[[0, 1, 2]] = 1.0  # (0,1), (0,2), (0,3)
    return pairs, w


def test_three_tdoas_fit_any_position_exactly():
    # the reason of the rule: three independent delays of noise are fitted with zero residual
    pairs = np.array([[0, 1], [0, 2], [0, 3]])
    rng = np.random.default_rng(3)
    taus = predicted_tdoas([300.0, 400.0, -500.0], SENSORS, pairs, c=1500.0)
    taus = taus + rng.normal(0, 1e-4, 3)  # 100-us errors: no source makes these delays
    x, _, _ = solve_source(SENSORS, pairs, taus, np.full(3, 1e-6), c=1500.0,
                           initial=[300.0, 400.0, -500.0])
    assert np.allclose(predicted_tdoas(x, SENSORS, pairs, c=1500.0), taus, atol=1e-9)


def test_three_held_tdoas_do_not_hold_a_source():
    pairs, w = three_held_and_crumbs()
    assert w.sum() >= CompetitionSettings().min_weight
    on = CompetitionSettings(min_redundant_tdoas=1)
    assert not holds_a_source(w, pairs, None, on)
    assert holds_a_source(w, pairs, None, CompetitionSettings())  # default: off
    w[3] = 1.0  # a fourth held TDOA: one degree of freedom left to test the fix
    assert holds_a_source(w, pairs, None, on)


def test_the_option_reaches_every_localizer():
    assert CompetitionSettings().min_redundant_tdoas == 0
    for kw in ({}, {"min_source_tdoas": 4.0}):
        settings = LocalizerSettings(min_redundant_tdoas=1, echo_ghost_lag_s=0.03, **kw)
        for loc in settings.localizers(SENSORS):
            assert isinstance(loc, MultiSourceLocalizer)
            assert loc.competition.min_redundant_tdoas == 1
            assert loc.competition.echo_ghost_lag_s == 0.03
    off = LocalizerSettings()
    assert all(loc.competition.min_redundant_tdoas == 0 for loc in off.localizers(SENSORS))
    assert whale_localizer(min_redundant_tdoas=2).competition.min_redundant_tdoas == 2
    assert whale_localizer(surface_z=None, min_redundant_tdoas=1).competition.min_redundant_tdoas == 1


def test_bad_value_is_refused():
    with pytest.raises(ValueError, match="min_redundant_tdoas"):
        CompetitionSettings(min_redundant_tdoas=-1)
