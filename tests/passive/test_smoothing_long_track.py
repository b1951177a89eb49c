"""A long track's graph is solved on a deep stack (fusion._stack): no segmentation fault.

GTSAM recurses once per state of a chain graph; ``fusion smooth`` of one track of 100,000 rows
ended in a segmentation fault (signal 11) on the main thread's 8 MiB stack. The test runs the
smoother in a thread with a 256 KiB stack, where a chain of 3,000 states overflows without the
deep stack, with the deep stack taken from 1,000 states on.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from fusion._stack import with_deep_stack

CHILD = textwrap.dedent("""
    import sys, threading
    import numpy as np
    from fusion.passive.smoothing import BearingSmoother, graph
    graph._DEEP_CHAIN = 1000
    t = np.arange(3000.0)
    z = 0.5 + 1e-4 * t + np.random.default_rng(1).normal(0, 0.01, t.size)
    smoother = BearingSmoother(sigma_bearing=0.01, q=1e-9, robust=sys.argv[1])
    out = []
    threading.stack_size(256 * 1024)
    th = threading.Thread(target=lambda: out.append(smoother.smooth(t, z)))
    th.start()
    th.join()
    assert len(out[0].times) == t.size and np.all(np.isfinite(out[0].sigma_bearing))
    print("ok")
""")


@pytest.mark.parametrize("robust", ["none", "huber"])
def test_long_track_on_a_small_stack_does_not_crash(robust):
    r = subprocess.run([sys.executable, "-c", CHILD, robust], capture_output=True, text=True,
                       check=False)
    assert r.returncode == 0 and r.stdout.strip() == "ok", (r.returncode, r.stderr[-500:])


def test_deep_stack_gives_the_same_result_and_raises_the_same_error():
    from fusion.passive.smoothing import BearingSmoother, graph

    t = np.arange(200.0)
    z = 0.5 + 1e-3 * t + np.random.default_rng(2).normal(0, 0.01, t.size)
    smoother = BearingSmoother(sigma_bearing=0.01, q=1e-8)
    here = smoother.smooth(t, z)
    there = with_deep_stack(smoother.smooth, t, z)
    np.testing.assert_array_equal(here.bearing, there.bearing)
    np.testing.assert_array_equal(here.sigma_rate, there.sigma_rate)
    assert graph._solve.__wrapped__ is not graph._solve  # the wrapper is in place
    with pytest.raises(ValueError, match="boom"):
        with_deep_stack(lambda: (_ for _ in ()).throw(ValueError("boom")))
