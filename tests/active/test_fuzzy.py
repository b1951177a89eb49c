"""Tests of the fuzzy inference engine and the paper's default rule base."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest
import skfuzzy as fuzz
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from fusion.active.fuzzy import (
    And,
    FuzzySystem,
    Gaussian,
    Is,
    LeftShoulder,
    LinguisticVariable,
    Not,
    Or,
    RightShoulder,
    Rule,
    Sigmoid,
    Trapezoidal,
    Triangular,
    expression_from_dict,
    load_system,
    membership_from_dict,
    save_system,
)
from fusion.active.rulebase import INPUT_NAMES, default_association_system

DATA_FILE = Path(__file__).parents[2] / "fusion" / "active" / "data" / "default_rules.json"


# --------------------------------------------------------------------------
# Independent reference: the aggregated set sampled on a fine grid
# --------------------------------------------------------------------------
def reference_crisp(system: FuzzySystem, activations: np.ndarray, *, n_grid: int,
                    use_skfuzzy: bool = True) -> np.ndarray:
    """Centroid of max_t min(alpha_t, mu_t) on a fine grid (skfuzzy.defuzz or np.trapezoid)."""
    low, high = system.output.universe
    y = np.linspace(low, high, n_grid)
    sets = np.stack([mf(y) for mf in system.output.terms.values()])  # (K, G)
    out = np.empty(activations.shape[1])
    for j in range(activations.shape[1]):
        aggregated = np.max(np.fmin(activations[:, j][:, None], sets), axis=0)
        if use_skfuzzy:
            out[j] = fuzz.defuzz(y, aggregated, "centroid")
        else:
            out[j] = np.trapezoid(y * aggregated, y) / np.trapezoid(aggregated, y)
    return out


def random_inputs(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Uniform random inputs over the default system's universes."""
    return {
        "likelihood": rng.uniform(0.0, 1.0, n),
        "score": rng.uniform(0.0, 1.0, n),
        "aspect_deg": rng.uniform(0.0, 180.0, n),
        "snr_db": rng.uniform(0.0, 40.0, n),
        "hotspot_distance_m": rng.uniform(0.0, 2000.0, n),
    }


def two_term_system(**kwargs) -> FuzzySystem:
    """x in [0, 1] with terms lo/hi; output y with triangles lo/hi."""
    x = LinguisticVariable("x", (0.0, 1.0), {"lo": LeftShoulder(0.0, 1.0), "hi": RightShoulder(0.0, 1.0)})
    z = LinguisticVariable("z", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
    y = LinguisticVariable(
        "y", (0.0, 1.0), {"lo": Triangular(0.0, 0.0, 1.0), "hi": Triangular(0.0, 1.0, 1.0)}
    )
    rules = kwargs.pop("rules", [Rule(x["hi"], "hi"), Rule(x["lo"], "lo")])
    return FuzzySystem([x, z], y, rules, **kwargs)


# --------------------------------------------------------------------------
# Membership functions
# --------------------------------------------------------------------------
class TestMembershipFunctions:
    def test_triangular_closed_form(self):
        """Triangle is 0 at the feet, 1 at the peak, linear between, 0 outside."""
        mf = Triangular(0.0, 1.0, 3.0)
        x = np.array([-1.0, 0.0, 0.5, 1.0, 2.0, 3.0, 4.0, np.inf, -np.inf])
        assert_allclose(mf(x), [0, 0, 0.5, 1, 0.5, 0, 0, 0, 0], atol=1e-15)

    def test_triangular_vertical_edge(self):
        """a == b gives a vertical left edge with value 1 at a, as skfuzzy.trimf."""
        mf = Triangular(0.0, 0.0, 0.5)
        x = np.array([-0.1, 0.0, 0.25, 0.5, 0.6])
        assert_allclose(mf(x), [0, 1, 0.5, 0, 0], atol=1e-15)
        assert_allclose(mf(x), fuzz.trimf(x, [0.0, 0.0, 0.5]), atol=1e-15)

    def test_trapezoidal_specular_paper_points(self):
        """The paper's specular set: 0 below 60, 0.5 at 70, 1 on [80, 100], 0 above 120."""
        mf = Trapezoidal(60.0, 80.0, 100.0, 120.0)
        x = np.array([0.0, 60.0, 70.0, 80.0, 90.0, 100.0, 110.0, 120.0, 180.0])
        assert_allclose(mf(x), [0, 0, 0.5, 1, 1, 1, 0.5, 0, 0], atol=1e-15)

    def test_shoulders(self):
        """Left shoulder falls from 1 to 0 on [a, b]; right shoulder rises; both handle inf."""
        x = np.array([-np.inf, 0.0, 100.0, 300.0, 500.0, 900.0, np.inf])
        assert_allclose(LeftShoulder(100.0, 500.0)(x), [1, 1, 1, 0.5, 0, 0, 0], atol=1e-15)
        assert_allclose(RightShoulder(100.0, 500.0)(x), [0, 0, 0, 0.5, 1, 1, 1], atol=1e-15)
        assert_allclose(RightShoulder(2.0, 2.0)(np.array([1.9, 2.0, 2.1])), [0, 1, 1])
        assert_allclose(LeftShoulder(2.0, 2.0)(np.array([1.9, 2.0, 2.1])), [1, 1, 0])

    def test_gaussian_and_sigmoid_closed_form(self):
        """Gaussian is exp(-1/2) one sigma out; the sigmoid is 1/2 at its centre."""
        g = Gaussian(2.0, 0.5)
        assert_allclose(g(np.array([2.0, 2.5, 1.5, 3.0])), [1, math.exp(-0.5), math.exp(-0.5), math.exp(-2)])
        s = Sigmoid(2.0, 3.0)
        assert_allclose(s(np.array([2.0, 3.0])), [0.5, 1 / (1 + math.exp(-3.0))], rtol=1e-14)
        assert_allclose(Sigmoid(0.0, 5.0)(np.array([-1e6, 1e6])), [0.0, 1.0])

    def test_agree_with_skfuzzy(self):
        """Every shape agrees with the scikit-fuzzy generator on a random grid."""
        x = np.sort(np.random.default_rng(3).uniform(-2.0, 12.0, 500))
        assert_allclose(Triangular(1.0, 4.0, 9.0)(x), fuzz.trimf(x, [1.0, 4.0, 9.0]), atol=1e-12)
        assert_allclose(Trapezoidal(1.0, 2.0, 5.0, 9.0)(x), fuzz.trapmf(x, [1.0, 2.0, 5.0, 9.0]), atol=1e-12)
        assert_allclose(Gaussian(4.0, 1.5)(x), fuzz.gaussmf(x, 4.0, 1.5), atol=1e-12)
        assert_allclose(Sigmoid(4.0, 1.3)(x), fuzz.sigmf(x, 4.0, 1.3), atol=1e-12)
        assert_allclose(LeftShoulder(1.0, 6.0)(x), fuzz.trapmf(x, [-10, -10, 1.0, 6.0]), atol=1e-12)

    def test_shape_preserved(self):
        """Any input shape comes back unchanged."""
        x = np.zeros((3, 4, 5))
        for mf in (Triangular(0, 1, 2), Gaussian(0, 1), Sigmoid(0, 1), RightShoulder(0, 1)):
            assert mf(x).shape == (3, 4, 5)

    @pytest.mark.parametrize(
        "factory, match",
        [
            (lambda: Triangular(0.0, 2.0, 1.0), "a <= b <= c"),
            (lambda: Triangular(1.0, 1.0, 1.0), "zero width"),
            (lambda: Trapezoidal(0.0, 3.0, 2.0, 4.0), "a <= b <= c <= d"),
            (lambda: LeftShoulder(2.0, 1.0), "a <= b"),
            (lambda: RightShoulder(float("nan"), 1.0), "finite"),
            (lambda: Gaussian(0.0, 0.0), "sigma must be > 0"),
            (lambda: Sigmoid(0.0, 0.0), "slope must be non-zero"),
            (lambda: Triangular("0", 1.0, 2.0), "must be a number"),
        ],
    )
    def test_bad_parameters(self, factory, match):
        """Invalid parameters raise ValueError naming the problem."""
        with pytest.raises(ValueError, match=match):
            factory()

    def test_dict_round_trip(self):
        """to_dict / membership_from_dict rebuild an equal function."""
        for mf in (Triangular(0, 1, 2), Trapezoidal(0, 1, 2, 3), LeftShoulder(0, 1),
                   RightShoulder(0, 1), Gaussian(1, 2), Sigmoid(1, -2)):
            assert membership_from_dict(mf.to_dict()) == mf
        with pytest.raises(ValueError, match="unknown membership function type"):
            membership_from_dict({"type": "bell", "a": 1})
        with pytest.raises(ValueError, match="expected parameters"):
            membership_from_dict({"type": "gaussian", "mean": 1})


# --------------------------------------------------------------------------
# Expressions and rules
# --------------------------------------------------------------------------
class TestExpressions:
    memberships = {
        ("a", "t"): np.array([0.2, 0.7, 1.0, 0.0]),
        ("b", "t"): np.array([0.5, 0.4, 0.0, 0.3]),
        ("c", "t"): np.array([0.9, 0.1, 0.6, 0.0]),
    }

    def test_and_or_not(self):
        """AND is min, OR is max, NOT is 1 - mu, via operators and constructors."""
        a, b, c = Is("a", "t"), Is("b", "t"), Is("c", "t")
        m = self.memberships
        assert_allclose((a & b).degree(m), np.minimum(m["a", "t"], m["b", "t"]))
        assert_allclose((a | b).degree(m), np.maximum(m["a", "t"], m["b", "t"]))
        assert_allclose((~a).degree(m), 1.0 - m["a", "t"])
        expected = np.maximum(np.minimum(m["a", "t"], 1.0 - m["b", "t"]), m["c", "t"])
        assert_allclose(Or(And(a, Not(b)), c).degree(m), expected)
        assert_allclose(((a & ~b) | c).degree(m), expected)

    def test_flattening_and_variables(self):
        """(a & b) & c is one three-way AND; variables lists every input read."""
        a, b, c = Is("a", "t"), Is("b", "t"), Is("c", "t")
        expr = (a & b) & c
        assert expr == And(a, b, c) and len(expr.operands) == 3
        assert (~(a | c)).variables() == frozenset({"a", "c"})

    def test_dict_round_trip(self):
        """Expressions survive to_dict / expression_from_dict."""
        expr = (Is("a", "t") & ~Is("b", "t")) | Is("c", "t")
        assert expression_from_dict(json.loads(json.dumps(expr.to_dict()))) == expr

    @pytest.mark.parametrize(
        "data, match",
        [
            ({"is": ["a"]}, "needs \\[variable, term\\]"),
            ({"xor": []}, "unknown expression operator"),
            ({"and": [{"is": ["a", "t"]}]}, "at least two operands"),
            ("a is t", "one key"),
        ],
    )
    def test_bad_expressions(self, data, match):
        """Malformed expression data raise ValueError."""
        with pytest.raises(ValueError, match=match):
            expression_from_dict(data)

    def test_bad_rules(self):
        """Rules validate weight and consequent; operands must be expressions."""
        with pytest.raises(ValueError, match="weight must be >= 0"):
            Rule(Is("a", "t"), "hi", weight=-1.0)
        with pytest.raises(ValueError, match="finite"):
            Rule(Is("a", "t"), "hi", weight=float("inf"))
        with pytest.raises(ValueError, match="consequent"):
            Rule(Is("a", "t"), "")
        with pytest.raises(ValueError, match="Expressions"):
            And(Is("a", "t"), "b is t")


# --------------------------------------------------------------------------
# Inference
# --------------------------------------------------------------------------
class TestInference:
    def test_additive_implication_sum_and_clip(self):
        """Same-consequent rules add weight * strength; the sum is clipped to 1."""
        x = LinguisticVariable("x", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        z = LinguisticVariable("z", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        y = LinguisticVariable(
            "y", (0.0, 1.0), {"lo": Triangular(0.0, 0.0, 1.0), "hi": Triangular(0.0, 1.0, 1.0)}
        )
        system = FuzzySystem(
            [x, z], y, [Rule(x["hi"], "hi", weight=0.6), Rule(z["hi"], "hi", weight=0.6),
                        Rule(~x["hi"], "lo", weight=0.5)],
        )
        result = system.evaluate({"x": np.array([0.5, 1.0, 0.25]), "z": np.array([0.5, 1.0, 0.0])})
        assert_allclose(result.strengths, [[0.5, 1.0, 0.25], [0.5, 1.0, 0.0], [0.5, 0.0, 0.75]])
        # hi: 0.6*0.5 + 0.6*0.5 = 0.6; 0.6 + 0.6 = 1.2 -> 1; 0.6*0.25 = 0.15.
        assert_allclose(result.activations[result.terms.index("hi")], [0.6, 1.0, 0.15])
        assert_allclose(result.activations[result.terms.index("lo")], [0.25, 0.0, 0.375])
        # Crisp value when only "hi" fires, fully: centroid of the right triangle = 2/3.
        assert result.crisp[1] == pytest.approx(2.0 / 3.0, abs=1e-12)

    def test_single_clipped_triangle_closed_form(self):
        """A right triangle cut at h has centroid (known closed form) for every h."""
        system = two_term_system(rules=[Rule(Is("x", "hi"), "hi")])
        h = np.linspace(0.01, 1.0, 50)
        result = system.evaluate({"x": h})
        # mu(y) = min(h, y) on [0, 1]: area h - h^2/2, moment 1/2 h - h^3/6.
        expected = (0.5 * h - h**3 / 6.0) / (h - 0.5 * h**2)
        assert_allclose(result.crisp, expected, rtol=1e-12)

    def test_default_system_agrees_with_skfuzzy_defuzz(self):
        """Crisp ranks equal skfuzzy.defuzz centroid of the same aggregated set (1e-3)."""
        system = default_association_system()
        result = system.evaluate(random_inputs(np.random.default_rng(11), 120))
        # skfuzzy's centroid loops in Python: a 4001-point grid holding every knot.
        reference = reference_crisp(system, result.activations, n_grid=4001)
        assert_allclose(result.crisp, reference, atol=1e-3)
        assert np.abs(result.crisp - reference).max() < 1e-5

    def test_activations_match_independent_rule_evaluation(self):
        """Activations equal the paper's rules evaluated by hand with skfuzzy memberships."""
        system = default_association_system()
        inputs = random_inputs(np.random.default_rng(5), 200)
        result = system.evaluate(inputs)
        li = inputs["likelihood"]
        likely = fuzz.interp_membership(np.array([0, 0.4, 0.7, 1]), np.array([0, 0, 1, 1.0]), li)
        unlikely = fuzz.interp_membership(np.array([0, 0.1, 0.4, 1]), np.array([1, 1, 0, 0.0]), li)
        somewhat = fuzz.trimf(li, [0.1, 0.4, 0.7])
        specular = fuzz.trapmf(inputs["aspect_deg"], [60, 80, 100, 120])
        snr_high = fuzz.interp_membership(np.array([0, 12, 20, 40.0]), np.array([0, 0, 1, 1.0]),
                                          inputs["snr_db"])
        good = fuzz.interp_membership(np.array([0, 0.5, 0.8, 1]), np.array([0, 0, 1, 1.0]), inputs["score"])
        near = fuzz.interp_membership(np.array([0, 100, 500, 2000.0]), np.array([1, 1, 0, 0.0]),
                                      inputs["hotspot_distance_m"])
        high = np.fmin(1.0, likely + 0.4 * specular + 0.6 * np.fmin(good, snr_high))
        low = np.fmin(1.0, unlikely + 0.6 * np.fmin(1 - specular, snr_high) + 0.8 * near)
        assert_allclose(result.activations, np.stack([low, somewhat, high]), atol=1e-12)

    @pytest.mark.parametrize("seed", range(6))
    def test_random_piecewise_linear_systems_vs_trapezoid(self, seed):
        """Exact centroid equals np.trapezoid on a fine grid for random linear output sets."""
        rng = np.random.default_rng(seed)
        terms = {}
        vertical = False
        for k in range(int(rng.integers(1, 5))):
            kind = rng.integers(0, 4)
            p = np.sort(rng.uniform(-3.0, 13.0, 4))
            if rng.random() < 0.2:
                p[1] = p[0]  # vertical edge inside the universe
                vertical = True
            terms[f"t{k}"] = [Triangular(*p[:3]), Trapezoidal(*p), LeftShoulder(*p[:2]),
                              RightShoulder(*p[2:])][kind]
        output = LinguisticVariable("y", (0.0, 10.0), terms)
        x = LinguisticVariable("x", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        rules = [Rule(x["hi"], term, weight=float(rng.uniform(0.2, 1.5))) for term in terms]
        system = FuzzySystem([x], output, rules, default=float("nan"))
        result = system.evaluate({"x": rng.uniform(0.0, 1.0, 30)})
        reference = reference_crisp(system, result.activations, n_grid=200_001, use_skfuzzy=False)
        ok = result.fired & np.isfinite(reference)
        assert ok.sum() > 0
        assert_allclose(result.crisp[ok], reference[ok], atol=1e-3)
        # The grid reference smears a vertical edge over one grid step (O(h) error).
        tight = 1e-4 if vertical else 1e-7
        assert np.abs(result.crisp[ok] - reference[ok]).max() < tight

    def test_many_terms_breakpoint_path(self):
        """Seven output terms (breakpoint integration, not inclusion-exclusion) vs trapezoid."""
        centres = np.linspace(0.0, 10.0, 7)
        output = LinguisticVariable(
            "y", (0.0, 10.0), {f"t{k}": Triangular(c - 2.0, c, c + 2.0) for k, c in enumerate(centres)}
        )
        x = LinguisticVariable("x", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0), "lo": LeftShoulder(0.0, 1.0)})
        rng = np.random.default_rng(21)
        rules = [Rule(x[["hi", "lo"][k % 2]], f"t{k}", weight=float(rng.uniform(0.2, 1.2))) for k in range(7)]
        system = FuzzySystem([x], output, rules)
        assert not hasattr(system._centroid, "ie_subset")
        result = system.evaluate({"x": rng.uniform(0.0, 1.0, 30)})
        reference = reference_crisp(system, result.activations, n_grid=200_001, use_skfuzzy=False)
        assert np.abs(result.crisp - reference).max() < 1e-7

    def test_vertical_edges_closed_form(self):
        """Step-shaped output sets inside the universe: exact centroids of rectangles."""
        output = LinguisticVariable(
            "y", (0.0, 10.0), {"step": RightShoulder(5.0, 5.0), "drop": Triangular(2.0, 2.0, 4.0)}
        )
        x = LinguisticVariable("x", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        alone = FuzzySystem([x], output, [Rule(x["hi"], "step")])
        h = np.array([0.1, 0.5, 1.0])
        assert_allclose(alone.evaluate({"x": h}).crisp, 7.5, rtol=1e-14)  # rectangle [5, 10]
        both = FuzzySystem([x], output, [Rule(x["hi"], "step"), Rule(x["hi"], "drop")])
        # Full cut: rectangle [5, 10] (area 5, moment 37.5) + triangle 2..4 (area 1, centroid 8/3).
        assert both.evaluate({"x": np.array([1.0])}).crisp[0] == pytest.approx((37.5 + 8 / 3) / 6, rel=1e-14)

    def test_smooth_output_sets_quadrature_error(self):
        """Gaussian/sigmoid output sets: quadrature centroid error < 1e-4 of the range."""
        output = LinguisticVariable(
            "y", (0.0, 10.0),
            {"lo": Sigmoid(3.0, -2.0), "mid": Gaussian(5.0, 1.2), "hi": Triangular(6.0, 9.0, 10.0)},
        )
        x = LinguisticVariable("x", (0.0, 1.0), {"lo": LeftShoulder(0, 1), "hi": RightShoulder(0, 1)})
        rules = [Rule(x["lo"], "lo"), Rule(x["hi"], "hi", weight=0.7), Rule(x["hi"], "mid", weight=0.9)]
        system = FuzzySystem([x], output, rules)
        result = system.evaluate({"x": np.random.default_rng(2).uniform(0.0, 1.0, 20)})
        reference = reference_crisp(system, result.activations, n_grid=1_000_001, use_skfuzzy=False)
        assert np.abs(result.crisp - reference).max() < 1e-4 * 10.0

    def test_batch_equals_one_by_one(self):
        """Evaluating candidates together or singly gives the same ranks."""
        system = default_association_system()
        inputs = random_inputs(np.random.default_rng(8), 25)
        batch = system.evaluate(inputs).crisp
        single = [system.evaluate({k: v[j:j + 1] for k, v in inputs.items()}).crisp[0] for j in range(25)]
        assert_allclose(batch, single, rtol=0, atol=1e-14)

    def test_scalars_broadcast_and_empty(self):
        """A scalar input broadcasts over the candidates; n = 0 gives empty results."""
        system = default_association_system()
        a = system.evaluate({"likelihood": np.array([0.2, 0.9]), "snr_db": 25.0, "score": 0.9})
        b = system.evaluate({"likelihood": np.array([0.2, 0.9]), "snr_db": np.array([25.0, 25.0]),
                             "score": np.array([0.9, 0.9])})
        assert_allclose(a.crisp, b.crisp)
        empty = system.evaluate({"likelihood": np.array([])})
        assert empty.crisp.shape == (0,) and empty.strengths.shape == (7, 0)


class TestSkippedAndDefault:
    def test_absent_inputs_skip_rules_and_log_once(self, caplog):
        """Rules reading absent inputs are skipped, reported in the result and logged once."""
        system = default_association_system()
        with caplog.at_level(logging.WARNING, logger="fusion.active.fuzzy"):
            first = system.evaluate({"likelihood": np.array([0.9, 0.05]), "snr_db": np.array([30.0, 5.0])})
            system.evaluate({"likelihood": np.array([0.5]), "snr_db": np.array([30.0])})
        assert first.skipped == (3, 4, 5, 6)
        assert first.missing == ("aspect_deg", "hotspot_distance_m", "score")
        assert not first.strengths[list(first.skipped)].any()
        messages = [r.getMessage() for r in caplog.records if "left out" in r.getMessage()]
        assert len(messages) == 1 and "aspect_deg" in messages[0]
        assert "rules[3, 4, 5, 6] left out" in messages[0]  # numbered as the API numbers them
        # Skipped rules contribute nothing: equal to a system without them.
        reduced = FuzzySystem(system.variables, system.output, system.rules[:3], default=0.5)
        assert_allclose(first.crisp, reduced.evaluate({"likelihood": np.array([0.9, 0.05])}).crisp)

    def test_no_rule_fires_gives_default(self):
        """Candidates where no rule fires get the documented default (midpoint or NaN)."""
        rules = [Rule(Is("z", "hi"), "hi")]
        result = two_term_system(rules=rules).evaluate({"z": np.array([0.0, 0.5])})
        assert not result.fired[0] and result.fired[1]
        assert result.crisp[0] == 0.5
        nan_result = two_term_system(rules=rules, default=float("nan")).evaluate({"z": np.array([0.0])})
        assert math.isnan(nan_result.crisp[0])

    def test_results_read_only(self):
        """Result arrays cannot be modified in place."""
        result = default_association_system().evaluate({"likelihood": np.array([0.3])})
        with pytest.raises(ValueError):
            result.crisp[0] = 1.0


class TestPaperRuleBase:
    def test_seven_rules_and_names(self):
        """The default system has the paper's seven rules over the documented inputs."""
        system = default_association_system()
        assert system.input_names == INPUT_NAMES
        assert len(system.rules) == 7
        assert [r.consequent for r in system.rules] == ["high", "low", "medium", "low", "low", "high", "high"]
        specular = system.variables[2].terms["specular"]
        assert specular(np.array([70.0]))[0] == pytest.approx(0.5)

    def test_likelihood_alone_orders_like_kalman(self):
        """With only the likelihood, rank is non-decreasing in it (the Kalman ordering)."""
        likelihood = np.linspace(0.0, 1.0, 2001)
        rank = default_association_system().evaluate({"likelihood": likelihood}).crisp
        assert np.all(np.diff(rank) >= -1e-12)
        assert rank[-1] > rank[0] + 0.5

    def test_clues_move_rank_in_the_paper_direction(self):
        """Hotspot near and non-specular high SNR lower the rank; specular, good NN raise it."""
        system = default_association_system()
        base = {"likelihood": np.full(1, 0.5), "snr_db": np.full(1, 30.0), "score": np.full(1, 0.0),
                "aspect_deg": np.full(1, 30.0), "hotspot_distance_m": np.full(1, np.inf)}

        def rank(**change):
            return system.evaluate({**base, **{k: np.full(1, v) for k, v in change.items()}}).crisp[0]

        assert rank(hotspot_distance_m=50.0) < rank()
        assert rank(aspect_deg=90.0) > rank()
        assert rank(score=0.95) > rank()

    def test_data_file_matches_default(self):
        """The shipped JSON rule file is the default system."""
        assert load_system(DATA_FILE).to_dict() == default_association_system().to_dict()


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=1, max_size=8),
    st.floats(0.0, 180.0),
    st.floats(0.0, 60.0),
)
def test_rank_stays_in_output_universe(likelihoods, aspect, snr):
    """Ranks lie within the output universe [0, 1] for any inputs."""
    system = default_association_system()
    n = len(likelihoods)
    result = system.evaluate({"likelihood": np.array(likelihoods), "aspect_deg": np.full(n, aspect),
                              "snr_db": np.full(n, snr)})
    assert np.all((result.crisp >= 0.0) & (result.crisp <= 1.0))
    assert np.all(result.activations <= 1.0) and np.all(result.activations >= 0.0)


# --------------------------------------------------------------------------
# Serialisation and validation
# --------------------------------------------------------------------------
class TestSerialisation:
    def test_dict_round_trip_same_results(self):
        """to_dict -> JSON -> from_dict rebuilds a system with identical output."""
        system = default_association_system()
        rebuilt = FuzzySystem.from_dict(json.loads(json.dumps(system.to_dict())))
        assert rebuilt.to_dict() == system.to_dict()
        inputs = random_inputs(np.random.default_rng(4), 50)
        assert_allclose(rebuilt.evaluate(inputs).crisp, system.evaluate(inputs).crisp, rtol=0, atol=0)

    def test_save_and_load(self, tmp_path):
        """save_system writes a file that load_system reads back; NaN default survives."""
        system = two_term_system(default=float("nan"))
        path = save_system(tmp_path / "rules.json", system)
        loaded = load_system(path)
        assert math.isnan(loaded.default)
        assert loaded.to_dict() == system.to_dict()
        assert not list(tmp_path.glob(".*tmp"))

    @pytest.mark.parametrize(
        "mutate, match",
        [
            (lambda d: d["rules"][0]["if"].update({"is": ["snr", "high"]}), "unknown input variable 'snr'"),
            (lambda d: d["rules"][0]["if"].update({"is": ["likelihood", "sure"]}), "has no term 'sure'"),
            (lambda d: d["rules"][0].update({"then": "huge"}), "has no term 'huge'"),
            (lambda d: d["rules"][0].update({"weight": -2}), "weight must be >= 0"),
            (lambda d: d["variables"][0]["terms"]["likely"].update({"type": "bell"}), "unknown membership"),
            (lambda d: d["variables"][1].update({"universe": [1, 0]}), "low < high"),
            (lambda d: d.update({"rules": []}), "at least one rule"),
            (lambda d: d["variables"].append(d["variables"][0]), "duplicate input variable"),
            (lambda d: d.update({"default": 3.0}), "output universe"),
            (lambda d: d.pop("output"), "missing key 'output'"),
            (lambda d: d.update({"format": "other"}), "format must be"),
        ],
    )
    def test_bad_rule_files(self, tmp_path, mutate, match):
        """Invalid rule sets raise ValueError naming the file and the problem."""
        data = default_association_system().to_dict()
        mutate(data)
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(data))
        with pytest.raises(ValueError, match=match) as info:
            load_system(path)
        assert str(info.value).startswith(str(path))

    def test_unreadable_files(self, tmp_path):
        """Missing files and invalid JSON raise ValueError starting with the path."""
        with pytest.raises(ValueError, match="cannot read fuzzy system"):
            load_system(tmp_path / "none.json")
        path = tmp_path / "broken.json"
        path.write_text("{not json")
        with pytest.raises(ValueError, match=r"broken\.json: invalid JSON"):
            load_system(path)


class TestInputValidation:
    @pytest.mark.parametrize(
        "inputs, match",
        [
            ({"likelihood": np.array([0.5, np.nan])}, "'likelihood': contains NaN"),
            ({"likelihood": np.zeros(3), "snr_db": np.zeros(2)}, "different lengths"),
            ({"likelihood": np.zeros((2, 2))}, "must be 1-D"),
            ({"snr": np.zeros(2)}, "no input for any variable"),
            ({}, "no input for any variable"),
            ({"likelihood": np.array(["a"])}, "not numeric"),
        ],
    )
    def test_bad_inputs(self, inputs, match):
        """Bad inputs raise ValueError naming the variable and problem."""
        with pytest.raises(ValueError, match=match):
            default_association_system().evaluate(inputs)

    def test_bad_systems(self):
        """Constructing an inconsistent system raises ValueError."""
        x = LinguisticVariable("x", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        y = LinguisticVariable("y", (0.0, 1.0), {"hi": RightShoulder(0.0, 1.0)})
        with pytest.raises(ValueError, match="also an input"):
            FuzzySystem([x], x, [Rule(x["hi"], "hi")])
        with pytest.raises(ValueError, match="quad_segments"):
            FuzzySystem([x], y, [Rule(x["hi"], "hi")], quad_segments=3)
        with pytest.raises(ValueError, match="has no term 'lo'"):
            x["lo"]
        with pytest.raises(ValueError, match="at least one term"):
            LinguisticVariable("x", (0.0, 1.0), {})
