"""Tests of fusion.passive.acquisition.starts: automatic track starts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from fusion.passive.acquisition import LineStarter


def test_line_starter_threshold_and_exclusion():
    """The threshold is the gamma quantile of a noise mean; a planted line is proposed unless a
    track holds it."""
    st = LineStarter(window_scans=20, false_alarm=1e-3)
    assert st.threshold == pytest.approx(stats.gamma.isf(1e-3, 20, scale=1 / 20))
    rng = np.random.default_rng(0)
    hist = rng.exponential(size=(20, 48, 16))
    hist[:, 30, 7] += 4.0
    lobes = np.full(16, 2.8)
    got = st.candidates(hist, held=[], lobe_beams=lobes)
    assert (got[0].beam, got[0].bin) == (30, 7)
    assert all(c.mean_power > st.threshold for c in got)
    held = st.candidates(hist, held=[(31.0, 8)], lobe_beams=lobes)
    assert all((c.beam, c.bin) != (30, 7) for c in held)
    with pytest.raises(ValueError, match="history"):
        st.candidates(hist[:5], held=[], lobe_beams=lobes)


def test_exclusion_zone_known_answer():
    """A cell is excluded within exclusion_lobes main lobes (in beams) and bin_guard bins of a
    held line, and not beyond either."""
    st = LineStarter(exclusion_lobes=2.0, bin_guard=1)
    lobes = np.full(16, 2.5)  # reach 5 beams
    held = [(30.0, 7)]
    assert st.excluded(35.0, 8, held=held, lobe_beams=lobes)
    assert st.excluded(25.5, 6, held=held, lobe_beams=lobes)
    assert not st.excluded(35.01, 7, held=held, lobe_beams=lobes)
    assert not st.excluded(30.0, 9, held=held, lobe_beams=lobes)
    assert not st.excluded(30.0, 7, held=[], lobe_beams=lobes)
