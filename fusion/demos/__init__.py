"""Parts of ``fusion demo``: one module per part, each with ``run_demo(out_dir, *, seed) -> dict``.

Parts are listed in :data:`fusion.demo.PARTS`; importing this package imports no part.
"""
