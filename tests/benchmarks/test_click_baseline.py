"""The baseline click localizer of benchmarks/click_baseline.py: known answers."""

from __future__ import annotations

import importlib.util
import itertools
from pathlib import Path

import numpy as np
import pytest

from fusion.simulate.clicks import simulate_clicks

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "click_baseline.py"


@pytest.fixture(scope="module")
def baseline():
    spec = importlib.util.spec_from_file_location("click_baseline", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_closed_form_recovers_exact_sources(baseline):
    """Exact TDOAs ``t_j - t_ref``: for every reference sensor and every choice of three or
    four pairs with it, one of the closed-form positions is the source (random sources in and
    around a bottom-mounted array)."""
    rng = np.random.default_rng(3)
    ang = np.linspace(0.0, 2.0 * np.pi, 4, endpoint=False)
    sensors = np.vstack([[0.0, 0.0, -1600.0],
                         np.column_stack([1500.0 * np.cos(ang), 1500.0 * np.sin(ang),
                                          rng.uniform(-1700.0, -1500.0, 4)])])
    c = 1500.0
    worst = 0.0
    for _ in range(20):
        src = np.array([*rng.uniform(-2500.0, 2500.0, 2), -rng.uniform(300.0, 1300.0)])
        t = np.linalg.norm(sensors - src, axis=1) / c
        for ref in range(5):
            others = [j for j in range(5) if j != ref]
            for k in (3, 4):
                for js in itertools.combinations(others, k):
                    fixes = baseline.closed_form_fixes(sensors, ref, js, t[list(js)] - t[ref], c)
                    assert fixes, (src, ref, js)
                    worst = max(worst, min(np.linalg.norm(f - src) for f in fixes))
    assert worst < 1e-4


def test_localizes_one_whale_noise_free(baseline):
    """One whale, noise-free audio, one 12 s window: one source, within 3 m of the whale where
    it emitted the click heard at the window centre."""
    sc = simulate_clicks(seed=2, n_sensors=5, n_sources=1, duration_s=12.0,
                         snr_db=float("inf"), n_transients=0)
    out = baseline.localize_recording(sc.audio, sc.fs, sc.sensors.positions,
                                      sc.sensors.sound_speed)
    assert len(out) == 1
    w = out[0]
    t_mid = 0.5 * (w["t_start"] + w["t_end"])
    src = sc.sources[0]
    mean = src.arrival_times.mean(axis=1)
    truth = np.array([np.interp(t_mid, mean, src.positions[:, k]) for k in range(3)])
    assert len(w["sources"]) == 1
    assert np.linalg.norm(np.asarray(w["sources"][0]) - truth) < 3.0
