"""Default fuzzy association rule base ("Target tracking using fuzzy logic association").

The paper's seven rules (Section 4, "System rules"), its membership functions
(Section 5) and additive implication (Section 6) as data, built from the objects
of :mod:`fusion.active.fuzzy`. Users who want other rules write their own system
as a JSON file (:func:`fusion.active.fuzzy.save_system` writes this one as a
starting point) and load it with :func:`fusion.active.fuzzy.load_system`.

Input variables
---------------
All inputs are 1-D float arrays with one value per candidate (track, detection)
pair. Values outside a universe are allowed: every membership function is
defined on the whole real line (shoulders stay at 0 or 1); ``+inf`` is allowed,
NaN is not.

``"likelihood"`` : dimensionless, universe [0, 1]
    Kalman-filter likelihood of the detection given the track, normalised so
    that the predicted measurement scores 1: ``L = exp(-d2 / 2)`` with
    ``d2 = nu^T S^-1 nu`` the squared Mahalanobis distance of the innovation
    ``nu`` (m) under the innovation covariance ``S`` (m^2). This is the ratio of
    the Gaussian likelihood to its peak value (the paper's "likelihood ratio
    which comes out of the Kalman filter"), without the ``1/(2 pi sqrt|S|)``
    factor, so that it does not depend on the track's uncertainty. For 2-D
    position measurements of the true target ``d2`` is chi-square with two
    degrees of freedom, so ``L`` is uniform on (0, 1]; ``L`` is then the
    probability that a true detection lies further out, and the terms below
    split that range evenly. Terms: ``unlikely`` (1 at L <= 0.1, 0 at L >= 0.4),
    ``somewhat_likely`` (triangle 0.1, 0.4, 0.7), ``likely`` (0 at L <= 0.4,
    1 at L >= 0.7). The three terms sum to 1 everywhere.
``"score"`` : dimensionless, universe [0, 1]
    Neural-network classifier score of the detection (Section 2.2; "NN" in the
    rules is this classifier, not nearest neighbour). Terms: ``poor`` (1 at
    <= 0.5, 0 at >= 0.8), ``good`` (0 at <= 0.5, 1 at >= 0.8).
``"aspect_deg"`` : degrees, universe [0, 180]
    Equivalent aspect angle of the echo; 90 deg is specular (broadside
    bistatic reflection). Term ``specular``: the paper's trapezoid, 0 below
    60 deg, rising linearly to 1 at 80 deg, 1 up to 100 deg, falling to 0 at
    120 deg (Section 5, Figure 3; 70 deg -> 0.5).
``"snr_db"`` : dB, universe [0, 40]
    Signal-to-noise ratio of the detection. Terms: ``low`` (1 at <= 12 dB,
    0 at >= 20 dB), ``high`` (0 at <= 12 dB, 1 at >= 20 dB).
``"hotspot_distance_m"`` : metres, universe [0, 2000]
    Distance from the detection to the nearest clutter-map hotspot
    (Section 2.4); ``+inf`` when there is no hotspot. Terms: ``near``
    (1 at <= 100 m, 0 at >= 500 m), ``far`` (the complement).

Output variable
---------------
``"rank"`` : dimensionless, universe [0, 1]. Terms: ``low`` (triangle 0, 0,
0.5), ``medium`` (triangle 0, 0.5, 1), ``high`` (triangle 0.5, 1, 1). The crisp
rank is the centroid of the union of the cut output sets; the detection with
the highest rank is associated with the track. When no rule fires the rank is
the system's default, 0.5 (no evidence either way).

Rules and weights
-----------------
==  =================================================  ======  ======
#   antecedent                                         rank    weight
==  =================================================  ======  ======
1   likelihood is likely                               high    1.0
2   likelihood is unlikely                             low     1.0
3   likelihood is somewhat_likely                      medium  1.0
4   aspect_deg is NOT specular AND snr_db is high      low     0.6
5   hotspot_distance_m is near                         low     0.8
6   aspect_deg is specular                             high    0.4
7   score is good AND snr_db is high                   high    0.6
==  =================================================  ======  ======

The paper prints the rules (Section 4) but neither its weights nor the shapes
of any membership function other than "specular". Choices made here: the
kinematic rules (1-3) carry full weight, so that with no other clue the rank
orders candidates exactly as the Kalman likelihood does (the paper's remark
that these rules alone reproduce the Kalman tracker); the clue rules adjust it
with smaller weights, the hotspot rule strongest because the clutter map is
built from this run's own detections, the specular rule weakest because
clutter echoes are specular as often as the target's.
"""

from __future__ import annotations

import numpy as np

from fusion.active.fuzzy import (
    FuzzySystem,
    LeftShoulder,
    LinguisticVariable,
    RightShoulder,
    Rule,
    Trapezoidal,
    Triangular,
)

__all__ = [
    "INPUT_NAMES",
    "OUTPUT_NAME",
    "default_association_system",
]

#: Names of the default system's input variables, in rule order.
INPUT_NAMES: tuple[str, ...] = (
    "likelihood",
    "score",
    "aspect_deg",
    "snr_db",
    "hotspot_distance_m",
)
#: Name of the default system's output variable.
OUTPUT_NAME: str = "rank"


def default_variables(
    *, hotspot_near_m: tuple[float, float] = (100.0, 500.0)
) -> tuple[LinguisticVariable, ...]:
    """Input variables of the paper's rule base (see the module docstring).

    Parameters
    ----------
    hotspot_near_m : (float, float), optional
        Distances to a hotspot where ``near`` is 1 and 0, m (default 100 and 500, sonar
        scales; :func:`fusion.active.settings.track_settings` scales them with the data's
        scatter). The universe is ``[0, 4 x`` the second``]``.

    Returns
    -------
    tuple of LinguisticVariable
        ``likelihood``, ``score``, ``aspect_deg``, ``snr_db``,
        ``hotspot_distance_m``, in that order.
    """
    return (
        LinguisticVariable(
            "likelihood",
            (0.0, 1.0),
            {
                "unlikely": LeftShoulder(0.1, 0.4),
                "somewhat_likely": Triangular(0.1, 0.4, 0.7),
                "likely": RightShoulder(0.4, 0.7),
            },
        ),
        LinguisticVariable(
            "score",
            (0.0, 1.0),
            {"poor": LeftShoulder(0.5, 0.8), "good": RightShoulder(0.5, 0.8)},
        ),
        LinguisticVariable(
            "aspect_deg",
            (0.0, 180.0),
            # Section 5, Figure 3: 1 on [80, 100] deg, 0 outside [60, 120] deg.
            {"specular": Trapezoidal(60.0, 80.0, 100.0, 120.0)},
        ),
        LinguisticVariable(
            "snr_db",
            (0.0, 40.0),
            {"low": LeftShoulder(12.0, 20.0), "high": RightShoulder(12.0, 20.0)},
        ),
        LinguisticVariable(
            "hotspot_distance_m",
            (0.0, 4.0 * hotspot_near_m[1]),
            {"near": LeftShoulder(*hotspot_near_m), "far": RightShoulder(*hotspot_near_m)},
        ),
    )


def default_output() -> LinguisticVariable:
    """Output variable ``rank`` in [0, 1] with terms low, medium, high.

    Returns
    -------
    LinguisticVariable
        Triangles (0, 0, 0.5), (0, 0.5, 1) and (0.5, 1, 1).
    """
    return LinguisticVariable(
        OUTPUT_NAME,
        (0.0, 1.0),
        {
            "low": Triangular(0.0, 0.0, 0.5),
            "medium": Triangular(0.0, 0.5, 1.0),
            "high": Triangular(0.5, 1.0, 1.0),
        },
    )


def default_rules(*, hotspot_near_m: tuple[float, float] = (100.0, 500.0)) -> tuple[Rule, ...]:
    """The paper's seven rules (Section 4) with the weights of the module table.

    Parameters
    ----------
    hotspot_near_m : (float, float), optional
        As in :func:`default_variables`.

    Returns
    -------
    tuple of Rule
        Rules 1-7 in the order of the module docstring's table.
    """
    likelihood, score, aspect, snr, hotspot = default_variables(hotspot_near_m=hotspot_near_m)
    return (
        Rule(likelihood["likely"], "high", weight=1.0),
        Rule(likelihood["unlikely"], "low", weight=1.0),
        Rule(likelihood["somewhat_likely"], "medium", weight=1.0),
        Rule(~aspect["specular"] & snr["high"], "low", weight=0.6),
        Rule(hotspot["near"], "low", weight=0.8),
        Rule(aspect["specular"], "high", weight=0.4),
        Rule(score["good"] & snr["high"], "high", weight=0.6),
    )


def default_association_system(
    *, hotspot_near_m: tuple[float, float] = (100.0, 500.0)
) -> FuzzySystem:
    """The paper's fuzzy association system: inputs, rules, output ``rank``.

    Parameters
    ----------
    hotspot_near_m : (float, float), optional
        Distances to a hotspot where ``near`` is 1 and 0, m (default 100 and 500); see
        :func:`default_variables`.

    Returns
    -------
    FuzzySystem
        Evaluate it with a mapping from any subset of :data:`INPUT_NAMES` to
        1-D arrays (one value per candidate); rules whose inputs are absent
        are skipped. ``result.crisp`` is the rank in [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> system = default_association_system()
    >>> result = system.evaluate({"likelihood": np.array([0.9, 0.05])})
    >>> bool(result.crisp[0] > result.crisp[1])
    True
    """
    if not (0.0 <= hotspot_near_m[0] < hotspot_near_m[1] and np.isfinite(hotspot_near_m[1])):
        raise ValueError(f"hotspot_near_m must be (full, none) with 0 <= full < none, got "
                         f"{hotspot_near_m!r}")
    return FuzzySystem(default_variables(hotspot_near_m=hotspot_near_m), default_output(),
                       default_rules(hotspot_near_m=hotspot_near_m), default=0.5)
