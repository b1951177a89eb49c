"""Parts of ``fusion demo``: one module per part, each with ``run_demo(out_dir, *, seed) -> dict``.

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
