"""Tests of the track quality indicator with hysteresis (flow steps 100-132)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fusion.io import read_table, write_table
from fusion.passive.quality import (
    SLLR0_CEILING_MARGIN,
    START,
    TrackQuality,
    TrackQualityIndicator,
    design_statistics,
    omega_for_beamwidth,
    tqi_transition,
)
from fusion.simulate.amplitudes import condition_snr_db, draw_amplitudes, draw_residuals

L, U, W, S = (TrackQuality.LOST, TrackQuality.UNCERTAIN, TrackQuality.LOW_SNR,
              TrackQuality.STRONG)
# method defaults: TL = -3.5, TU = 1.75, TS = 7, LH = 1.5, SH = 2
# => TL + LH = -2, TU + LH = 3.25, TS + SH = 9, TS - SH = 5

# (previous, SLLR_0, SLLR_1, |ES| > ERR_max, expected, path through the flow)
BRANCHES = [
    (L, -2.5, 0.0, False, L, "102 yes, 104 yes -> 106"),
    (L, -2.0, 0.0, False, L, "104: equal to TL + LH is lost"),
    (L, -1.0, 0.0, False, U, "104 no -> 108 yes -> 112 yes -> 114"),
    (L, 3.0, 10.0, False, U, "112: below TU + LH"),
    (L, 4.0, 10.0, True, U, "112 no -> 122 yes -> 114"),
    (L, 4.0, 8.0, False, W, "122 no -> 124 no -> 126 yes -> 128"),
    (L, 4.0, 9.5, False, S, "126 no -> 132 no -> 130"),
    (U, -3.5, 10.0, False, L, "102 no -> 110 yes (equal) -> 106"),
    (U, -3.0, 10.0, False, U, "110 no -> 108 yes -> 112 yes -> 114"),
    (U, 3.0, 10.0, False, U, "112: 3.0 < TU + LH"),
    (U, 3.25, 8.5, False, W, "112: TU + LH itself passes -> 126 yes -> 128"),
    (U, 4.0, 9.0, False, S, "126: TS + SH itself is strong"),
    (U, 4.0, 10.0, True, U, "122 yes -> 114"),
    (W, -4.0, 10.0, False, L, "110 yes -> 106"),
    (W, 1.0, 10.0, False, U, "108 no -> 116 yes -> 118 yes -> 114"),
    (W, 1.75, 8.0, False, W, "118: TU itself passes -> 122 no -> 124 no -> 126 yes -> 128"),
    (W, 2.0, 8.9, False, W, "126: below TS + SH stays low"),
    (W, 2.0, 9.5, False, S, "126 no -> 132 no -> 130"),
    (W, 2.0, 9.5, True, U, "122 yes -> 114"),
    (S, -3.6, 10.0, False, L, "110 yes -> 106"),
    (S, 1.7, 10.0, False, U, "118 yes -> 114"),
    (S, 2.0, 10.0, True, U, "122 yes -> 114"),
    (S, 2.0, 5.5, False, S, "124 yes -> 132 no (5.5 >= TS - SH) -> 130"),
    (S, 2.0, 5.0, False, S, "132: TS - SH itself stays strong"),
    (S, 2.0, 4.9, False, W, "132 yes -> 128"),
    (START, -3.5, 0.0, False, L, "start: 102 no -> 110 yes -> 106"),
    (START, 0.0, 0.0, False, W, "start: 108 no -> 116 no -> 122 no -> 124 no -> 126 -> 128"),
    (START, 0.0, 0.0, True, U, "start: 116 no -> 122 yes -> 114"),
    (START, 0.0, 9.0, False, S, "start: 126 no -> 132 no -> 130"),
    (START, 0.0, 8.0, False, W, "start: 126 yes -> 128"),
]


@pytest.mark.parametrize(("prev", "s0", "s1", "high", "expected", "path"), BRANCHES,
                         ids=[b[5] for b in BRANCHES])
def test_flow_branch(prev, s0, s1, high, expected, path):
    """Each branch of flow steps 102-132 gives the state derived by hand."""
    got = tqi_transition(np.array([prev]), np.array([s0]), np.array([s1]), np.array([high]))
    assert got.dtype == np.int8
    assert TrackQuality(int(got[0])) is expected, path


def test_flow_branches_vectorised_at_once():
    """All branches evaluated in one call give the same states as one by one."""
    prev, s0, s1, high, expected, _ = map(list, zip(*BRANCHES, strict=True))
    got = tqi_transition(np.array(prev), np.array(s0), np.array(s1), np.array(high))
    assert_array_equal(got, np.array([int(e) for e in expected]))


def test_single_thresholds_branches():
    """With LH = SH = 0 the upward and downward thresholds coincide."""
    prev = np.array([L, L, U, S, W])
    s0 = np.array([-3.0, -3.5, 2.0, 2.0, 2.0])
    s1 = np.array([0.0, 0.0, 7.0, 6.9, 7.0])
    got = tqi_transition(prev, s0, s1, np.zeros(5, bool), lh=0.0, sh=0.0)
    assert_array_equal(got, [U, L, S, W, S])


def test_labels_and_codes():
    """States carry the file names and order lost < uncertain < low_snr < strong."""
    assert [s.label for s in TrackQuality] == ["lost", "uncertain", "low_snr", "strong"]
    assert TrackQuality.from_label("low_snr") is TrackQuality.LOW_SNR
    assert L < U < W < S
    with pytest.raises(ValueError, match="unknown TQI state"):
        TrackQuality.from_label("weak")


def test_design_statistics_match_simulated_cells():
    """C_i, O_i equal the mean and std of simulated cell power above the noise mean."""
    rng = np.random.default_rng(11)
    for snr_db, looks in ((3.0, 1), (10.0, 1), (6.0, 4)):
        c, o = design_statistics(snr_db, n_looks=looks)
        a = draw_amplitudes(np.full(200_000, snr_db), rng=rng, n_looks=looks) - 1.0
        assert_allclose(a.mean(), c[0], rtol=0.02)
        assert_allclose(a.std(), o[0], rtol=0.02)
    tqi = TrackQualityIndicator(snr0_db=3.0, snr1_db=10.0)
    s0, s1 = 10 ** 0.3, 10.0
    assert_allclose(tqi.design_mean, [s0, s1])
    assert_allclose(tqi.design_std, np.sqrt([1 + 2 * s0, 1 + 2 * s1]))


def scalar_reference(amp, res, *, snr0_db=3.0, snr1_db=10.0, hysteresis=True):
    """The TQI of one track written plainly, update by update, from the method text."""
    tl, tu, ts, lh, sh = -3.5, 1.75, 7.0, 1.5, 2.0
    if not hysteresis:
        lh_d, sh_d = 0.0, 0.0
    else:
        lh_d, sh_d = lh, sh
    lim0 = (tl - lh, tu + lh + 0.25)  # default SLLR_0 ceiling: TU + LH + 0.25
    lim1 = (ts - 2 * sh, ts + 2 * sh)
    c0, c1 = 10 ** (snr0_db / 10), 10 ** (snr1_db / 10)
    o0, o1 = np.sqrt(1 + 2 * c0), np.sqrt(1 + 2 * c1)
    p0, p1 = c0 / o0, c1 / o1
    n, omega, t_err, b = 0.5, 0.25, 3.0, 0.1
    sllr0 = min(max(0.0, lim0[0]), lim0[1])
    sllr1 = min(max(0.0, lim1[0]), lim1[1])
    es, var, snr = 0.0, 1.0, 0.0
    prev = "start"
    out = []
    for a, r in zip(amp, res, strict=True):
        ahat = a - 1.0
        sllr0 = max(min(sllr0 + p0 * (ahat / o0 - p0 / 2), lim0[1]), lim0[0])
        sllr1 = max(min(sllr1 + p1 * (ahat / o1 - 0.85 * p1), lim1[1]), lim1[0])
        snr = snr + 0.1 * (ahat - snr)
        ke = abs(snr) / (1.744 + abs(snr))
        dev = r - es
        es = es + b * dev
        var = var + b * (dev**2 - var)
        sresvar = np.sqrt(var * b / (2 - b))
        too_big = abs(es) > n * ke / (2 * omega) + t_err * sresvar
        # flow 102-132
        if prev == "lost":
            is_lost = sllr0 <= tl + lh_d
        else:
            is_lost = sllr0 <= tl
        if is_lost:
            state = "lost"
        else:
            if prev in ("uncertain", "lost"):
                unc = sllr0 < tu + lh_d
            elif prev in ("low_snr", "strong"):
                unc = sllr0 < tu
            else:
                unc = False
            if unc or too_big:
                state = "uncertain"
            elif prev == "strong":
                state = "low_snr" if sllr1 < ts - sh_d else "strong"
            elif sllr1 < ts + sh_d:
                state = "low_snr"
            else:
                state = "strong"
        out.append(state)
        prev = state
    return out


@pytest.mark.parametrize("hysteresis", [True, False])
def test_vectorised_equals_scalar_reference(hysteresis):
    """update() over many tracks equals the plain per-track reference, update by update."""
    rng = np.random.default_rng(5)
    n_upd, n_trk = 120, 24
    snr = rng.choice([15.0, 9.3, 0.0, 6.0, -np.inf], size=(1, n_trk))
    snr = np.where(np.arange(n_upd)[:, None] < rng.integers(20, 100, n_trk), snr, -np.inf)
    amp = draw_amplitudes(snr, rng=rng)
    res = draw_residuals(snr, rng=rng, bias_deg=rng.choice([0.0, 3.0], size=n_trk))
    tqi = TrackQualityIndicator(hysteresis=hysteresis)
    states = np.array([tqi.update(amp[k], res[k]) for k in range(n_upd)])
    for j in range(n_trk):
        ref = scalar_reference(amp[:, j], res[:, j], hysteresis=hysteresis)
        assert [TrackQuality(int(s)).label for s in states[:, j]] == ref
    # the batch entry point agrees with streaming
    assert_array_equal(TrackQualityIndicator(hysteresis=hysteresis).run(amp, res).state, states)


def test_update_runs_all_flow_states():
    """The reference comparison above is not vacuous: every state occurs."""
    rng = np.random.default_rng(5)
    snr = np.repeat([15.0, 9.3, 0.0, -np.inf], 60)[:, None]
    amp, res = draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng)
    states = set(TrackQualityIndicator().run(amp, res).state[:, 0].tolist())
    assert states == {0, 1, 2, 3}


def _amplitude_for_llr(tqi, llr, i):
    """Cell power whose LLR_i is `llr` (inverting LLR_0 = p0 (a0 - p0/2), LLR_1 = p1 (a1 - 0.85 p1))."""
    c, o = tqi.design_mean[i], tqi.design_std[i]
    p = c / o
    return 1.0 + o * (np.asarray(llr) / p + (0.5 if i == 0 else 0.85) * p)


@pytest.mark.parametrize(("i", "ramp", "expected_single"), [(1, [1.0, 1.0, 1.0, 1.25], (W, S)),
                                                             (0, [2.0], (W, U))])
def test_no_flicker_around_a_threshold(i, ramp, expected_single):
    """An SLLR dithering around TS (or TU) by less than the hysteresis never flickers."""
    tqi = TrackQualityIndicator()
    llr = np.concatenate([ramp, np.tile([-0.5, 0.5], 100)])
    amp = _amplitude_for_llr(tqi, llr, i)[:, None]
    h = tqi.run(amp, np.zeros_like(amp))
    h1 = TrackQualityIndicator(hysteresis=False).run(amp, np.zeros_like(amp))
    sllr = h.sllr1 if i == 1 else h.sllr0
    threshold = 7.0 if i == 1 else 1.75
    dither = sllr[len(ramp):, 0]
    assert dither.min() < threshold <= dither.max()  # the input really straddles the threshold
    assert h.n_changes()[0] <= 1
    assert h1.n_changes()[0] >= 150
    assert set(h1.state[len(ramp):, 0].tolist()) == {int(s) for s in expected_single}


def test_fewer_changes_with_hysteresis_on_noisy_near_threshold_input():
    """At the SNRs where an LLR has zero mean, hysteresis changes state far less often."""
    rng = np.random.default_rng(8)
    for kind in ("near_strong", "near_lost"):
        snr = np.full((300, 40), condition_snr_db(kind))
        amp, res = draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng)
        n_h = TrackQualityIndicator().run(amp, res).n_changes().sum()
        n_1 = TrackQualityIndicator(hysteresis=False).run(amp, res).n_changes().sum()
        assert n_h < 0.6 * n_1


def test_loss_declared_without_added_lag():
    """Lost is declared at the same update with and without hysteresis after a fresh loss."""
    rng = np.random.default_rng(3)
    n = 300
    onset = rng.integers(40, 120, n)
    before = rng.choice([15.0, 9.3, 6.0, 1.0], n)
    k = np.arange(200)[:, None]
    snr = np.where(k < onset, before, -np.inf)
    amp, res = draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng)
    s_h = TrackQualityIndicator().run(amp, res).state
    s_1 = TrackQualityIndicator(hysteresis=False).run(amp, res).state
    # hysteresis is lost whenever the single-threshold variant is
    assert np.all(s_h[s_1 == L] == L)
    cols = np.arange(n)
    fresh = (s_h[onset - 1, cols] != L) & (s_1[onset - 1, cols] != L)
    assert fresh.sum() > 200
    after = k >= onset
    first_h = ((s_h == L) & after).argmax(axis=0)
    first_1 = ((s_1 == L) & after).argmax(axis=0)
    assert np.all(((s_1 == L) & after).any(axis=0))
    assert_array_equal(first_h[fresh], first_1[fresh])


def test_strong_and_lost_on_clear_inputs():
    """Clearly strong input ends strong; noise alone ends lost."""
    rng = np.random.default_rng(0)
    snr = np.array([[20.0, -np.inf]]).repeat(60, axis=0)
    h = TrackQualityIndicator().run(draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng))
    assert list(h.state[-1]) == [S, L]


def test_manoeuvre_bias_makes_uncertain():
    """A residual bias beyond ERR_max at strong SNR gives uncertain, via step 122."""
    rng = np.random.default_rng(1)
    snr = np.full((80, 1), 15.0)
    res = draw_residuals(snr, rng=rng, bias_deg=np.where(np.arange(80)[:, None] >= 40, 4.0, 0.0))
    h = TrackQualityIndicator().run(draw_amplitudes(snr, rng=rng), res)
    assert np.all(h.state[20:40, 0] == S)
    assert np.all(h.state[60:, 0] == U)
    assert np.all(h.sllr1[60:, 0] > 9.0)  # the SNR alone would say strong


def test_active_mask_keeps_memory():
    """Inactive trackers keep their state and SLLRs; NaN inputs are fine for them."""
    tqi = TrackQualityIndicator()
    s0 = tqi.update([30.0, 30.0], [0.0, 0.0])
    before = tqi.memory
    s1 = tqi.update([np.nan, 0.0], [np.nan, 0.0], active=[False, True])
    assert s1[0] == s0[0]
    assert tqi.memory.sllr0[0] == before.sllr0[0]
    assert tqi.memory.sllr1[1] < before.sllr1[1]


def test_omega_for_beamwidth():
    """Omega makes the detector's linear range n / Omega one beamwidth."""
    assert omega_for_beamwidth(2.0) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="beamwidth_deg"):
        omega_for_beamwidth(0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"snr0_db": 10.0, "snr1_db": 3.0}, "must exceed"),
        ({"lh": -1.0}, "hysteresis constants"),
        ({"tl": 2.0, "tu": 1.0}, "below uncertain"),
        ({"omega": 0.0}, "omega"),
        ({"residual_smoothing": 0.0}, "residual_smoothing"),
        ({"sllr1_limits": (5.0, 5.0)}, "sllr1_limits"),
        ({"n_looks": 0}, "n_looks"),
        ({"snr0_db": float("nan")}, "snr0_db"),
    ],
)
def test_bad_configuration(kwargs, match):
    """Bad constructor options raise ValueError naming the option."""
    with pytest.raises(ValueError, match=match):
        TrackQualityIndicator(**kwargs)


def test_bad_inputs():
    """Wrong shapes, NaN and negative amplitudes raise ValueError."""
    tqi = TrackQualityIndicator()
    tqi.update(np.ones(3), np.zeros(3))
    with pytest.raises(ValueError, match="shape"):
        tqi.update(np.ones(4), np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        tqi.update(np.array([1.0, np.nan, 1.0]), np.zeros(3))
    with pytest.raises(ValueError, match=">= 0"):
        tqi.update(np.array([1.0, -1.0, 1.0]), np.zeros(3))
    with pytest.raises(ValueError, match="one shape"):
        tqi.run(np.ones((5, 2)), np.ones((5, 3)))


def _write_amplitudes(path, rng):
    snr = np.concatenate([np.full(40, 15.0), np.full(40, -np.inf)])
    cols = {"track_id": [], "time": [], "amplitude": [], "residual": []}
    for tid, n in ((3, 80), (1, 50)):
        cols["track_id"].append(np.full(n, tid))
        cols["time"].append(np.arange(n) * 2.0)
        cols["amplitude"].append(draw_amplitudes(snr[:n], rng=rng))
        cols["residual"].append(draw_residuals(snr[:n], rng=rng))
    cols = {k: np.concatenate(v) for k, v in cols.items()}
    # interleave the two tracks' rows: the output must keep the input order
    order = np.argsort(np.concatenate([np.arange(80), np.arange(50) + 0.5]), kind="stable")
    cols = {k: v[order] for k, v in cols.items()}
    write_table(path, cols)
    return cols


def test_cli_round_trip(tmp_path, run_cli):
    """fusion tqi writes the input rows in order plus the TQI each track gets on its own."""
    rng = np.random.default_rng(2)
    cols = _write_amplitudes(tmp_path / "a.csv", rng)
    code, _, err = run_cli("tqi", "--amplitudes", tmp_path / "a.csv", "--out", tmp_path / "q.csv")
    assert code == 0, err
    q = read_table(tmp_path / "q.csv", required=("track_id", "time", "amplitude", "residual",
                                                 "tqi"), text=("tqi",), integer=("track_id",))
    assert_array_equal(q["track_id"], cols["track_id"])
    assert_allclose(q["amplitude"], cols["amplitude"], atol=1e-6)
    for tid in (1, 3):
        rows = cols["track_id"] == tid
        ref = TrackQualityIndicator().run(q["amplitude"][rows], q["residual"][rows])
        assert list(q["tqi"][rows]) == list(ref.labels()[:, 0])
    assert set(q["tqi"]) <= {"lost", "uncertain", "low_snr", "strong"}
    assert q["tqi"][cols["track_id"] == 3][-1] == "lost"
    assert q["tqi"][cols["track_id"] == 1][30] == "strong"
    # options reach the indicator: single thresholds give at least as many changes
    code, _, err = run_cli("tqi", "--amplitudes", tmp_path / "a.csv", "--out",
                           tmp_path / "q1.csv", "--no-hysteresis", "--diagnostics")
    assert code == 0, err
    q1 = read_table(tmp_path / "q1.csv", required=("sllr0", "sllr1", "tqi"), text=("tqi",))
    assert np.all(q1["sllr0"] >= -5.0) and np.all(q1["sllr1"] <= 11.0)


@pytest.mark.parametrize("ceiling", [3.5, 4.75, 6.25])
def test_loss_delay_follows_the_sllr0_ceiling(ceiling):
    """After a loss, lost comes after about (TM_0 - TL) / (p_0^2 / 2) updates (noise drift)."""
    rng = np.random.default_rng(11)
    onset, n = 40, 400
    snr = np.where(np.arange(onset + 80)[:, None] < onset, 15.0, -np.inf) * np.ones((1, n))
    amp, res = draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng)
    tqi = TrackQualityIndicator(sllr0_limits=(-5.0, ceiling))
    s = tqi.run(amp, res).state[onset:]
    delay = np.argmax(s == L, axis=0) + 1  # updates of noise until lost
    drift = tqi.p[0] ** 2 / 2  # E[LLR_0] under noise alone is -p_0^2 / 2
    # the walk drifts down by `drift` per update with the exponential's skew: a mean-drift
    # estimate of the first passage from the ceiling below TL (independent of the flow code)
    expected = (ceiling - tqi.tl) / drift
    assert np.all((s == L).any(axis=0))
    assert abs(np.median(delay) / expected - 1.0) < 0.12


def test_default_sllr0_ceiling_is_just_above_leaving_uncertain():
    """The default SLLR_0 ceiling lets a track leave uncertain (>= TU + LH) by the set margin."""
    tqi = TrackQualityIndicator()
    assert tqi.sllr0_limits == (tqi.tl - tqi.lh, tqi.tu + tqi.lh + SLLR0_CEILING_MARGIN)
    # a strong track after an uncertain spell reaches low_snr/strong again
    rng = np.random.default_rng(4)
    snr = np.r_[np.full(30, -np.inf), np.full(60, 15.0)][:, None]
    h = tqi.run(draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng))
    assert h.state[-1, 0] == S


def test_cli_sllr0_max_reaches_the_indicator(tmp_path, run_cli):
    """--sllr0-max sets the ceiling: the diagnostics never exceed it, and bad values are refused."""
    rng = np.random.default_rng(2)
    _write_amplitudes(tmp_path / "a.csv", rng)
    code, _, err = run_cli("tqi", "--amplitudes", tmp_path / "a.csv", "--out",
                           tmp_path / "q.csv", "--sllr0-max", "6", "--diagnostics")
    assert code == 0, err
    q = read_table(tmp_path / "q.csv", required=("sllr0",))
    assert q["sllr0"].max() == pytest.approx(6.0)
    code, _, err = run_cli("tqi", "--amplitudes", tmp_path / "a.csv", "--out",
                           tmp_path / "q2.csv", "--sllr0-max", "-9")
    assert code == 2 and "--sllr0-max" in err


@pytest.mark.parametrize(
    ("content", "args", "match"),
    [
        ("track_id,time,amplitude\n0,0,1\n", (), "missing required column"),
        ("track_id,time,amplitude,residual\n0,0,nan,0\n", (), "amplitude"),
        ("track_id,time,amplitude,residual\n0,0,-1,0\n", (), "negative"),
        ("track_id,time,amplitude,residual\n0,1,1,0\n0,1,1,0\n", (), "must be distinct"),
        ("track_id,time,amplitude,residual\n0,0,1,0\n", ("--snr1-db", "1"), "must exceed"),
        (None, (), "no such file"),
    ],
)
def test_cli_bad_input_exit_2(tmp_path, run_cli, content, args, match):
    """Bad input gives exit code 2 and one line on stderr, and no output file."""
    path = tmp_path / "a.csv"
    if content is not None:
        path.write_text(content)
    code, out, err = run_cli("tqi", "--amplitudes", path, "--out", tmp_path / "q.csv", *args)
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert match in err
    assert not (tmp_path / "q.csv").exists()
