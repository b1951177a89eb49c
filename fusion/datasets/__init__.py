"""Readers of recorded data sets used to test the library against reality."""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.datasets import *` imports them all.
__all__ = [
    "autoferry",
    "autoferry_files",
]
