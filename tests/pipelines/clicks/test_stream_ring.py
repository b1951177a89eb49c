"""The click stream's audio buffer: cuts equal the recording's samples through growth and moves."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion.pipelines.clicks.stream import _AudioRing


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 50), min_size=1, max_size=40), st.integers(0, 1000),
       st.integers(0, 2**31 - 1))
def test_cuts_are_the_recording_samples(block_sizes, start, seed):
    """After every append and drop, any cut inside the held span is the recording's samples."""
    rng = np.random.default_rng(seed)
    total = sum(block_sizes)
    audio = rng.standard_normal((total, 3)).astype(np.float32)
    ring = _AudioRing(start)
    first = start
    for n in block_sizes:
        ring.append(first, audio[first - start:first - start + n])
        first += n
        assert ring.end == first
        drop = int(rng.integers(ring.start, ring.end + 1))
        ring.drop_before(drop)
        assert ring.start == drop
        if ring.end > ring.start:
            a = int(rng.integers(ring.start - 5, ring.end))
            b = int(rng.integers(max(a, ring.start) + 1, ring.end + 6))
            got_a, x = ring.cut(a, b)
            assert got_a == max(a, ring.start)
            np.testing.assert_array_equal(x, audio[got_a - start:min(b, ring.end) - start])


def test_blocks_must_be_contiguous():
    """A block that does not start where the held audio ends is refused."""
    ring = _AudioRing(10)
    ring.append(10, np.zeros((4, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="contiguous"):
        ring.append(15, np.zeros((4, 2), dtype=np.float32))
