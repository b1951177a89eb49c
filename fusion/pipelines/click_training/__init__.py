"""Deprecated import path: use :mod:`fusion.pipelines.clicks.training` instead; this goes in the next release.

Why: the click pipeline's modules are one package. (A package rather than a module, so that the
moved file keeps its history.)
"""

from fusion._deprecated import moved_names

__all__ = [  # noqa: F822 (served by __getattr__)
    "CandidateSet", "TdoaLabels", "label_windows", "scenario_labels", "simulated_training_set",
    "train_from_candidates", "varied_scenario",
]

__getattr__ = moved_names(
    __name__, "fusion.pipelines.clicks.training", __all__, shown="fusion.pipelines.clicks.training"
)
