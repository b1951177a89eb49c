"""The click chain as one package: audio in, validated and associated TDOAs out, at any length.

It chains the click front-end stages of :mod:`fusion.clicks` (replica, detection, click maps,
TDOA refinement, validation, association) and feeds :mod:`fusion.localization` through
:mod:`fusion.pipelines.localization`; it holds no algorithm of its own and reads no files. A
user builds a :class:`ClickFrontEnd` and calls it on a recording's audio, or runs a long
recording chunk by chunk.

Modules: :mod:`~fusion.pipelines.clicks.frontend` (:class:`ClickFrontEnd`, the whole front end
on one window at a time), :mod:`~fusion.pipelines.clicks.stream` (its streaming part: audio
blocks in, measured windows out), :mod:`~fusion.pipelines.clicks.chunks` (a long recording in
independent chunks of consecutive windows) and :mod:`~fusion.pipelines.clicks.training` (the
validator trained from labelled or simulated recordings).

The front end's names are served here on first use (PEP 562), so that importing one module of
the package does not load the others.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["LLR_THRESHOLD", "ClickFrontEnd", "ClickWindow", "WindowTdoa", "default_validator",
           "window_starts"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module("fusion.pipelines.clicks.frontend"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
