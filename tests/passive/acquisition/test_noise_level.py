"""The noise level of a cube, and `fusion passive` normalising the cubes that need it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fusion.io import Cube
from fusion.passive.acquisition import noise_mean_level, normalize_spectra
from fusion.pipelines.passive import unit_noise_cubes
from fusion.pipelines.passive.noise import normalized


def _cube(scale: float, seed: int = 0) -> Cube:
    rng = np.random.default_rng(seed)
    power = scale * rng.exponential(size=(80, 6, 24))
    power[:, 2, 11] *= 30.0  # a strong line in one beam and bin: the median ignores it
    return Cube(power=power, freqs=np.arange(24) * 2.0 + 100.0, scan_period=1.0, aperture=10.0,
                sound_speed=1500.0)


@pytest.mark.parametrize("scale", [1.0, 0.01, 40.0, 3e4])
def test_noise_level_is_the_scale_of_chi_square_noise(scale):
    """Unit-mean noise times `scale` has level `scale` (within the estimate's scatter)."""
    assert noise_mean_level(_cube(scale).power) == pytest.approx(scale, rel=0.05)


def test_noise_level_is_the_median_of_the_normaliser():
    """Cross-check: the level is the median of power / normalize_spectra over the first scans."""
    p = _cube(7.0).power
    ratio = p[:60] / normalize_spectra(p[:60], pool_scans=60)
    assert noise_mean_level(p) == pytest.approx(float(np.median(ratio)), rel=1e-12)


def test_passive_normalises_only_cubes_off_unit_noise():
    """By default a raw cube is normalised (as --normalize) and a normalised one is used as read
    (as --no-normalize); the decision is printed and recorded."""
    unit, raw = _cube(1.0), _cube(250.0, seed=1)
    cubes, record, err = unit_noise_cubes([unit, raw], None, ["u.npz", "r.npz"])
    assert cubes[0] is unit
    np.testing.assert_array_equal(cubes[1].power, normalized(raw).power)
    assert [record[k]["normalized"] for k in ("u.npz", "r.npz")] == [False, True]
    assert record["r.npz"]["noise_level"] == pytest.approx(250.0, rel=0.05)
    assert err[0].startswith("u.npz: median noise level ") and "used as read" in err[0]
    assert err[1].startswith("r.npz: median noise level 25") and "normalised" in err[1]
    # given: no estimate, no line
    forced, rec, lines = unit_noise_cubes([unit], True, ["u.npz"])
    np.testing.assert_array_equal(forced[0].power, normalized(unit).power)
    assert rec == {"u.npz": {"normalized": True, "source": "given"}} and lines == []
    kept, _, lines = unit_noise_cubes([dataclasses.replace(raw)], False, ["r.npz"])
    np.testing.assert_array_equal(kept[0].power, raw.power)
    assert lines == []
