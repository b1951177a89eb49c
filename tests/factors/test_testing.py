"""Tests of factors.testing: the Jacobian check catches wrong Jacobians."""

import gtsam
import numpy as np
import pytest

from factors.testing import analytic_jacobians, assert_jacobians, numerical_jacobians


def _factor(scale: float = 1.0) -> gtsam.CustomFactor:
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.1, 2.0]))

    def error(this, values, jacobians):
        x = values.atVector(this.keys()[0])
        pose = values.atPose2(this.keys()[1])
        e = np.array([x[0] ** 2 + pose.x(), np.sin(x[1]) + pose.theta()])
        if jacobians is not None:
            jacobians[0] = scale * np.array([[2 * x[0], 0.0], [0.0, np.cos(x[1])]])
            r = pose.rotation().matrix()
            jacobians[1] = np.array([[r[0, 0], r[0, 1], 0.0], [0.0, 0.0, 1.0]])
        return e

    return gtsam.CustomFactor(noise, [1, 2], error)


@pytest.mark.parametrize("seed", range(5))
def test_correct_jacobians_pass(seed):
    """Vector and Pose2 (tangent-space) Jacobians match central differences."""
    rng = np.random.default_rng(seed)
    v = gtsam.Values()
    v.insert(1, rng.normal(size=2))
    v.insert(2, gtsam.Pose2(*rng.normal(size=3)))
    assert_jacobians(_factor(), v)
    num = numerical_jacobians(_factor(), v)
    ana = analytic_jacobians(_factor(), v)
    assert [h.shape for h in num] == [(2, 2), (2, 3)] == [h.shape for h in ana]


def test_wrong_jacobian_fails():
    """A 1 % error in one Jacobian is caught."""
    v = gtsam.Values()
    v.insert(1, np.array([0.3, 0.5]))
    v.insert(2, gtsam.Pose2(1, 2, 0.7))
    with pytest.raises(AssertionError, match="Jacobian for key"):
        assert_jacobians(_factor(scale=1.01), v)
