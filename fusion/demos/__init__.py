"""Parts of ``fusion demo``: one module per part, each with ``run_demo(out_dir, *, seed) -> dict``.

A part writes its files into `out_dir` (its own output folder), simulates its scenarios from the
seed `seed`, and returns its measured summary numbers; each ``run_demo`` documents what it writes
and returns, and refers here for the rest.

Parts are listed in :data:`fusion.demo.PARTS`; importing this package imports no part.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.demos import *` imports them all.
__all__ = [
    "acquisition",
    "active",
    "clicks",
    "crossings",
    "passive",
    "smoothing",
    "summary",
    "tma",
    "tqi",
]
