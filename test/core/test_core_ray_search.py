"""The compiled ray search's parts against independent numpy: roots, Taylor and noise-free rays."""

import math

import numpy as np
from numpy.polynomial import polynomial
from prvo_core_testing import crowd, crowd_rays
import pytest

from prvo_planner.core import PlannerConfig
from prvo_planner.core.feasibility import ray_gaps
from prvo_planner.core.moments import condition_moments
from prvo_planner.core.ray_solver import polynomial_roots, quadratic_roots


def separated_roots(rng, count, low=0.02, high=0.98, gap=0.05):
    """Return COUNT sorted values in [LOW, HIGH], at least GAP apart."""
    while True:
        roots = np.sort(rng.uniform(low, high, count))
        if count < 2 or np.min(np.diff(roots)) >= gap:
            return roots


def companion_roots_inside(coefficients):
    """Real roots in (0, 1) of ascending COEFFICIENTS by numpy's companion-matrix eigenvalues."""
    roots = polynomial.polyroots(np.trim_zeros(coefficients, 'b'))
    real = roots.real[np.abs(roots.imag) < 1e-9]
    return np.sort(real[(real > 0.0) & (real < 1.0)])


def found_inside(roots):
    """Return the roots in (0, 1) of a NaN-padded tuple, sorted."""
    roots = np.array(roots)
    return np.sort(roots[(roots > 0.0) & (roots < 1.0)])


@pytest.mark.parametrize('shape', ['four real', 'two real, two complex', 'biquadratic',
                                   'cubic', 'quadratic', 'linear'])
def test_polynomial_roots_of_every_degree_match_companion_eigenvalues(shape):
    rng = np.random.default_rng(list(shape.encode()))
    for _ in range(200):
        scale = 10.0 ** rng.uniform(-3.0, 3.0)
        if shape == 'four real':
            coefficients = polynomial.polyfromroots(separated_roots(rng, 4))
        elif shape == 'two real, two complex':
            centre, spread = rng.uniform(-1.0, 2.0), rng.uniform(0.1, 1.0)
            coefficients = polynomial.polymul(polynomial.polyfromroots(separated_roots(rng, 2)),
                                              [centre * centre + spread * spread, -2.0 * centre,
                                               1.0])
        elif shape == 'biquadratic':
            # Symmetric about its centre: the depressed quartic has no odd term.
            centre = rng.uniform(0.3, 0.7)
            inner, outer = rng.uniform(0.03, 0.12), rng.uniform(0.18, 0.28)
            coefficients = polynomial.polyfromroots(
                [centre - outer, centre - inner, centre + inner, centre + outer])
        elif shape == 'cubic':
            coefficients = np.append(polynomial.polyfromroots(separated_roots(rng, 3)), 0.0)
        elif shape == 'quadratic':
            coefficients = np.append(polynomial.polyfromroots(separated_roots(rng, 2)),
                                     [0.0, 0.0])
        else:
            coefficients = np.append(polynomial.polyfromroots(separated_roots(rng, 1)),
                                     [0.0, 0.0, 0.0])
        coefficients = scale * coefficients
        expected = companion_roots_inside(coefficients)
        found = found_inside(polynomial_roots(*coefficients))
        assert found.shape == expected.shape, (coefficients, found, expected)
        np.testing.assert_allclose(found, expected, rtol=0.0, atol=1e-9)


def test_quadratic_roots_handle_a_vanishing_leading_term_and_no_real_root():
    np.testing.assert_allclose(np.sort(quadratic_roots(0.06, -0.5, 1.0)), [0.2, 0.3], atol=1e-15)
    first, second = quadratic_roots(-0.25, 1.0, 0.0)
    assert first == 0.25 and math.isnan(second)
    assert all(math.isnan(root) for root in quadratic_roots(1.0, 0.0, 1.0))
    assert all(math.isnan(root) for root in quadratic_roots(1.0, 0.0, 0.0))


def assert_gaps_match(gap_direction, lower, upper, t, accepted):
    """Assert that the intervals hold the accepted grid speeds, except within 1e-6 of ends."""
    inside = np.zeros_like(accepted)
    near_boundary = np.zeros_like(accepted)
    for direction, low, high in zip(gap_direction, lower, upper, strict=True):
        inside[direction] |= (t >= low) & (t <= high)
        near_boundary[direction] |= (np.abs(t - low) < 1e-6) | (np.abs(t - high) < 1e-6)
    assert np.all((inside == accepted) | near_boundary)


def taylor_surrogate(mean, variance, k, preferred, t):
    """
    ``mean(t) - k T(t)`` on the grid T, with ascending coefficients MEAN and VARIANCE.

    ``T`` expands ``sqrt(variance)`` to second order around the point of ``{mean >= 0}`` in
    [0, 1] nearest PREFERRED (PREFERRED itself where there is none): roots by numpy's
    companion matrix, derivatives by ``polyder``.
    """
    preferred = min(max(preferred, 0.0), 1.0)
    candidates = [preferred, 0.0, 1.0] + list(companion_roots_inside(mean))
    usable = [point for point in candidates if polynomial.polyval(point, mean) >= 0.0]
    centre = min(usable, key=lambda point: abs(point - preferred)) if usable else preferred
    sigma = math.sqrt(max(polynomial.polyval(centre, variance), 0.0))
    slope_var = polynomial.polyval(centre, polynomial.polyder(variance))
    curve_var = polynomial.polyval(centre, polynomial.polyder(variance, 2))
    slope = slope_var / (2.0 * sigma) if sigma > 0.0 else 0.0
    curve = (curve_var / (2.0 * sigma) - slope_var ** 2 / (4.0 * sigma ** 3)
             if sigma > 0.0 else 0.0)
    offset = t - centre
    return polynomial.polyval(t, mean) - k * (sigma + slope * offset + 0.5 * curve * offset ** 2)


def test_taylor_intervals_match_dense_evaluation_of_the_surrogate():
    rng = np.random.default_rng(41)
    t = np.linspace(0.0, 1.0, 2001)
    for _ in range(12):
        ego, neighbours = crowd(rng, int(rng.integers(1, 4)), 0.15)
        config = PlannerConfig(receding_gate=False, time_horizon=math.inf, num_directions=24,
                               k=float(rng.uniform(0.5, 3.0)), actuation_cov=0.01 * np.eye(2))
        encounter, layout, directions, means, variances = crowd_rays(ego, neighbours,
                                                                         config)
        preferred = rng.uniform(-0.2, 1.2, directions.shape[0])
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, 'taylor', False, preferred)
        accepted = np.ones((directions.shape[0], t.size), dtype=bool)
        for neighbour in range(encounter.origin.shape[0]):
            for direction in range(directions.shape[0]):
                accepted[direction] &= taylor_surrogate(
                    means[neighbour, direction, 0], variances[neighbour, direction, 0],
                    config.k, preferred[direction], t) >= 0.0
        assert_gaps_match(gap_direction, lower, upper, t, accepted)


@pytest.mark.parametrize('receding_gate, time_horizon',
                         [(False, math.inf), (True, 3.0), (False, 5.0)])
def test_noise_free_intervals_match_dense_evaluation_of_the_means(receding_gate, time_horizon):
    rng = np.random.default_rng(43)
    t = np.linspace(0.0, 1.0, 2001)
    for _ in range(10):
        ego, neighbours = crowd(rng, int(rng.integers(1, 9)), 0.0)
        config = PlannerConfig(receding_gate=receding_gate, time_horizon=time_horizon,
                               num_directions=24, model='rvo')
        encounter, layout, directions, means, variances = crowd_rays(ego, neighbours,
                                                                         config)
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, 'exact', True, directions[:, 0])
        # Independent: each condition's closed-form mean at every grid velocity.
        velocities = (config.max_speed * t[None, :, None] * directions[:, None, :]).reshape(-1, 2)
        grid_means, _ = condition_moments(encounter.origin, encounter.cov,
                                          encounter.combined_radius, velocities, time_horizon,
                                          receding_gate)
        meets = grid_means >= 0.0
        pair_accepted = meets[..., 0]
        if receding_gate:
            pair_accepted = pair_accepted | meets[..., 1]
        if math.isfinite(time_horizon):
            pair_accepted = pair_accepted | (meets[..., -3] & meets[..., -2]) | meets[..., -1]
        accepted = np.all(pair_accepted, axis=0).reshape(directions.shape[0], t.size)
        assert_gaps_match(gap_direction, lower, upper, t, accepted)
