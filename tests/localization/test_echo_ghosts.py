"""The echo-ghost test: a candidate made of another's clicks heard along bottom echoes."""

from __future__ import annotations

import numpy as np
import pytest

from factors.tdoa import predicted_tdoas, solve_source
from fusion.localization.competition import CompetitionSettings, compete
from fusion.localization.echo_ghosts import (
    echo_explained,
    echo_ghosts,
    echo_only_sensors,
    surface_alternatives,
)
from fusion.localization.surface_paths import surface_paths
from fusion.localization.surfaces import WindowTdoas
from fusion.simulate.tdoa_sets import all_pairs

C = 1500.0
SENSORS = np.array([[0.0, 0, -1600], [3000, 0, -1590], [0, 3000, -1610], [3000, 3000, -1595],
                    [1500, 1500, -1605]])
WHALE = np.array([1200.0, 900.0, -700.0])
SIGMA = 2e-7


def bottom_lags(x):
    """Bottom-echo lag of each sensor (images through a flat floor 20 m below), s."""
    floor = SENSORS[:, 2] - 20.0
    image = SENSORS.copy()
    image[:, 2] = 2 * floor - SENSORS[:, 2]
    return (np.linalg.norm(image - x, axis=1) - np.linalg.norm(SENSORS - x, axis=1)) / C


def ghost_set():
    """Delays of the whale with the echo at sensor 0 or 2 in place of the click: the four
    TDOAs the seed-8003 ghost was built of (pairs (0,1), (0,3), (1,2), (2,3))."""
    pairs = np.array([[0, 1], [0, 3], [1, 2], [2, 3]])
    lag = bottom_lags(WHALE)
    taus = predicted_tdoas(WHALE, SENSORS, pairs, c=C)
    taus = taus + np.array([lag[0], lag[0], -lag[2], lag[2]])
    return pairs, taus


def test_echo_delays_fit_a_position_of_their_own():
    # why the test is needed: the four echo delays fix a source far from the whale
    pairs, taus = ghost_set()
    x, _, _ = solve_source(SENSORS, pairs, taus, np.full(4, SIGMA), c=C, initial=WHALE)
    assert np.allclose(predicted_tdoas(x, SENSORS, pairs, c=C), taus, atol=1e-8)
    assert np.linalg.norm(x - WHALE) > 10.0


def test_echo_lags_on_two_sensors_explain_the_ghost():
    pairs, taus = ghost_set()
    r = taus - predicted_tdoas(WHALE, SENSORS, pairs, c=C)
    assert echo_explained(r, pairs, np.full(4, 3 * SIGMA), max_lag_s=0.03) == (True, 2)
    # an echo arrives after its click: the same delays with the lags' signs reversed are not
    assert not echo_explained(-r, pairs, np.full(4, 3 * SIGMA), max_lag_s=0.03)[0]
    # lags longer than the echo window are not echoes
    assert not echo_explained(r, pairs, np.full(4, 3 * SIGMA), max_lag_s=1e-4)[0]


@pytest.mark.parametrize("offset", [[30.0, 0, 0], [0, 40.0, 10.0], [15.0, -20.0, 25.0]])
def test_a_second_whale_nearby_is_not_a_ghost(offset):
    pairs = all_pairs(5)
    other = WHALE + np.array(offset)
    taus = np.concatenate([predicted_tdoas(WHALE, SENSORS, pairs, c=C),
                           predicted_tdoas(other, SENSORS, pairs, c=C)])
    both = np.vstack([pairs, pairs])
    pred = np.vstack([predicted_tdoas(x, SENSORS, both, c=C) for x in (WHALE, other)])
    held = np.zeros((2, 20), dtype=bool)
    held[0, :10] = held[1, 10:] = True
    assert not echo_ghosts(taus, np.full(20, SIGMA), both, pred, held, max_lag_s=0.03).any()


def test_echo_ghost_is_dropped_by_the_competition_and_kept_without_the_test():
    pairs = all_pairs(5)
    ghost_pairs, ghost_taus = ghost_set()
    all_p = np.vstack([pairs, ghost_pairs])
    taus = np.concatenate([predicted_tdoas(WHALE, SENSORS, pairs, c=C), ghost_taus])
    t = WindowTdoas(SENSORS, all_p, taus, np.full(len(taus), SIGMA), c=C)
    ghost_x, _, _ = solve_source(SENSORS, ghost_pairs, ghost_taus, np.full(4, SIGMA), c=C,
                                 initial=WHALE)
    starts = np.vstack([WHALE, ghost_x])
    w = np.zeros((2, 14))
    w[0, :10] = w[1, 10:] = 1.0  # each settled on its own delays (a later round)
    kw = {"start_scale_s": 1e-4, "weights": w, "settled": [True, True]}
    off = compete(t, starts, settings=CompetitionSettings(), **kw)  # default: off
    on = compete(t, starts, settings=CompetitionSettings(echo_ghost_lag_s=0.03), **kw)
    assert off.positions.shape[0] == 2
    assert on.positions.shape[0] == 1
    assert np.linalg.norm(on.positions[0] - WHALE) < 0.5


def test_a_slipped_surface_echo_ghost_is_explained_along_the_surface_paths():
    # seed 8000's ghost: delays between a click and its sign-inverted surface echo at sensor
    # 3, half a carrier period (12.5 us at 40 kHz) off the path's delay, read as direct delays
    whales = np.vstack([WHALE, WHALE + 900.0])  # the whale and the ghost's position
    ghost_pairs = np.array([[0, 3], [1, 3], [2, 3], [0, 4]])
    pairs = np.vstack([ghost_pairs, all_pairs(5)[:6]])
    alt, alt_pairs, inverted, _ = surface_alternatives(whales, SENSORS, pairs, C, 0.0)
    taus = np.concatenate([alt[0, :4, 2] + 12.5e-6,  # direct at i, echo at j, slipped
                           predicted_tdoas(WHALE, SENSORS, pairs[4:], c=C)])
    held = np.zeros((2, 10), dtype=bool)
    held[0, 4:] = held[1, :4] = True  # the whale holds six direct delays, the ghost four
    pred = np.vstack([predicted_tdoas(x, SENSORS, pairs, c=C) for x in whales])
    assert inverted[:, 2].all() and not inverted[:, 0].any()
    kw = {"max_lag_s": 0.03, "reflected": alt, "inverted": inverted,
          "reflected_pairs": alt_pairs}
    sig = np.full(10, SIGMA)
    assert echo_ghosts(taus, sig, pairs, pred, held, slip_s=25e-6, **kw).tolist() == [False, True]
    # without the slip the delays are 60 sigma off every path: not explained
    assert not echo_ghosts(taus, sig, pairs, pred, held, slip_s=0.0, **kw).any()


def test_a_source_hearing_a_sensor_only_by_its_echo_is_an_alias():
    # seed 8009's alias: the whale's ten direct delays read with sensors 1 and 4 swapped for
    # their surface images fit a position 820 m away; sensors 1 and 4 are heard by echo only
    pairs = all_pairs(5)
    t = WindowTdoas(SENSORS, pairs, predicted_tdoas(WHALE, SENSORS, pairs, c=C),
                    np.full(10, SIGMA), c=C)
    wide = surface_paths(t, 0.0)
    alias = np.zeros(40, dtype=bool)
    image = {1, 4}
    for m, (i, j) in enumerate(pairs):  # the column reading sensor 1 and 4 as images
        h = {(False, False): 0, (True, True): 1, (False, True): 2, (True, False): 3}[
            (int(i) in image, int(j) in image)]
        alias[h * 10 + m] = True
    truth = np.zeros(40, dtype=bool)
    truth[:10] = True
    truth[2 * 10 + 3] = True  # and a direct-surface delay of sensor 4: heard both ways
    held = np.vstack([truth, alias])
    assert echo_only_sensors(wide.tdoas.sensors, wide.tdoas.pairs, held, 0.0).tolist() == [
        False, True]
    # the competition: delays that a position fits read with sensors 1 and 4 as images
    x = WHALE + np.array([300.0, -200.0, 150.0])
    cols = np.flatnonzero(alias)[np.argsort(np.flatnonzero(alias) % 10)]  # by measurement
    t2 = WindowTdoas(SENSORS, pairs, wide.tdoas.predicted(x)[cols], np.full(10, SIGMA), c=C)
    wide2 = surface_paths(t2, 0.0)
    kw = {"start_scale_s": 1e-4, "weights": alias[None, :].astype(float), "settled": [True],
          "groups": wide2.measured, "surface_z": 0.0}
    off = compete(wide2.tdoas, x[None, :], **kw, settings=CompetitionSettings())  # default off
    on = compete(wide2.tdoas, x[None, :], **kw,
                 settings=CompetitionSettings(drop_echo_only_sensors=True))
    assert off.positions.shape[0] == 1
    assert on.positions.shape[0] == 0
