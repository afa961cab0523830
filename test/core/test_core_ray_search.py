"""The compiled ray search's parts against independent numpy: roots, Taylor and noise-free rays."""

import math

import numpy as np
from numpy.polynomial import polynomial
from prvo_core_testing import crowd, crowd_rays
import pytest

from prvo_planner.core import PlannerConfig
from prvo_planner.core.feasibility import ray_gaps
from prvo_planner.core.moments import condition_moments
from prvo_planner.core.ray_search import achieved_margins, link_margins, ray_links
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
    """
    Assert that the intervals hold the accepted grid speeds, except within 1e-6 of ends.

    ACCEPTED (M, T) per direction, or a list of such arrays: each direction must match one.
    """
    variants = accepted if isinstance(accepted, list) else [accepted]
    inside = np.zeros_like(variants[0])
    near_boundary = np.zeros_like(variants[0])
    for direction, low, high in zip(gap_direction, lower, upper, strict=True):
        inside[direction] |= (t >= low) & (t <= high)
        near_boundary[direction] |= (np.abs(t - low) < 1e-6) | (np.abs(t - high) < 1e-6)
    assert np.all(np.any([np.all((inside == variant) | near_boundary, axis=1)
                          for variant in variants], axis=0))


def taylor_surrogate(mean, variance, k, preferred, t, tie=None):
    """
    ``mean(t) - k T(t)`` on the grid T, with ascending coefficients MEAN and VARIANCE.

    ``T`` expands ``sqrt(variance)`` to second order around the point of ``{mean >= 0}`` in
    [0, 1] nearest PREFERRED (PREFERRED itself where there is none): roots by numpy's
    companion matrix, derivatives by ``polyder``. At a root the sign of the mean is rounding:
    with TIE (a bool) a candidate whose mean is within 1e-12 of zero, relative to the
    coefficients, is taken as usable or not; None decides by the computed sign.
    """
    preferred = min(max(preferred, 0.0), 1.0)
    candidates = [preferred, 0.0, 1.0] + list(companion_roots_inside(mean))
    scale = 1e-12 * float(np.max(np.abs(mean)))

    def is_usable(point):
        value = polynomial.polyval(point, mean)
        return value >= 0.0 if tie is None or abs(value) > scale else tie

    usable = [point for point in candidates if is_usable(point)]
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
        # Where the centre's choice is a rounding tie (a root of the mean), either choice.
        variants = []
        for tie in (None, True, False):
            accepted = np.ones((directions.shape[0], t.size), dtype=bool)
            for neighbour in range(encounter.origin.shape[0]):
                for direction in range(directions.shape[0]):
                    accepted[direction] &= taylor_surrogate(
                        means[neighbour, direction, 0], variances[neighbour, direction, 0],
                        config.k, preferred[direction], t, tie) >= 0.0
            variants.append(accepted)
        assert_gaps_match(gap_direction, lower, upper, t, variants)


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


def bivariate_value(coefficients, x, y):
    """Evaluate ``sum c_k x^i y^j``, the monomials by degree (x^d, x^(d-1) y, ..., y^d)."""
    value, index = 0.0, 0
    for degree in range(5):
        for power_y in range(degree + 1):
            if index == len(coefficients):
                return value
            value += coefficients[index] * x ** (degree - power_y) * y ** power_y
            index += 1
    return value


def test_ray_links_restrict_every_neighbour_to_its_robots_rays():
    rng = np.random.default_rng(71)
    pair_counts, ray_counts, conditions = np.array([2, 3, 1]), np.array([4, 2, 5]), 5
    pairs, rays = int(pair_counts.sum()), int(ray_counts.sum())
    mean_fit = rng.normal(size=(pairs, 6, conditions))
    variance_fit = rng.normal(size=(pairs, 15, conditions))
    angles = rng.uniform(0.0, 2.0 * np.pi, rays)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    robot_margins = rng.uniform(0.5, 3.0, size=(3, conditions))
    enabled = rng.uniform(size=pairs) < 0.5
    (means, variances, margins, link_ray, link_pair, link_enabled, starts, ray_local, ray_robot,
     pair_robot) = ray_links(mean_fit, variance_fit, directions, pair_counts, ray_counts,
                             robot_margins, enabled)
    assert starts.tolist() == [[0, 2, 5], [0, 4, 6], [0, 8, 14]]
    assert ray_local.tolist() == [0, 1, 2, 3, 0, 1, 0, 1, 2, 3, 4]
    assert ray_robot.tolist() == [0] * 4 + [1] * 2 + [2] * 5
    assert pair_robot.tolist() == [0, 0, 1, 1, 1, 2]
    link = 0
    t = np.linspace(0.0, 1.0, 7)
    for robot in range(3):
        for pair in range(starts[0, robot], starts[0, robot] + pair_counts[robot]):
            for ray in range(starts[1, robot], starts[1, robot] + ray_counts[robot]):
                assert (link_ray[link], link_pair[link]) == (ray, pair)
                assert link_enabled[link] == enabled[pair]
                np.testing.assert_array_equal(margins[link], robot_margins[robot])
                for condition in range(conditions):
                    for fit, polynomials in ((mean_fit, means), (variance_fit, variances)):
                        expected = [bivariate_value(fit[pair, :, condition], *(point * directions[
                            ray])) for point in t]
                        np.testing.assert_allclose(
                            polynomial.polyval(t, polynomials[:, link, condition]), expected,
                            rtol=0.0, atol=1e-12)
                link += 1
    assert link == means.shape[1] == 19


def combined_margin(means, variances, enabled, has_receding, has_horizon):
    """Return the k one point's conditions meet (docs/method.md, section 7), one by one."""
    def margin(mean, variance):
        sigma = math.sqrt(max(variance, 0.0))
        if sigma == 0.0:
            return math.inf if mean >= 0.0 else -math.inf
        return mean / sigma

    margins = [margin(mean, variance) for mean, variance in zip(means, variances, strict=True)]
    best = margins[0]
    if has_receding and enabled:
        best = max(best, margins[1])
    if has_horizon:
        joint = min(margins[-3], margins[-2])
        best = max(best, math.sqrt((joint * joint - 1.0) / 2.0) if joint >= 1.0 else joint - 1.0,
                   margins[-1])
    return best


@pytest.mark.parametrize('has_receding, has_horizon', [(False, False), (True, False),
                                                       (False, True), (True, True)])
def test_achieved_margins_and_link_margins_meet_the_closed_form(has_receding, has_horizon):
    rng = np.random.default_rng(81 + 2 * has_receding + has_horizon)
    conditions = 1 + has_receding + 3 * has_horizon
    count = 400
    means = rng.normal(size=(count, conditions)) * rng.uniform(0.0, 3.0, size=(count, 1))
    variances = rng.uniform(-0.1, 1.0, size=(count, conditions)) ** 2
    # Some conditions known exactly (sigma = 0), some zero means among them.
    variances[rng.uniform(size=variances.shape) < 0.1] = 0.0
    means[rng.uniform(size=means.shape) < 0.05] = 0.0
    enabled = rng.uniform(size=count) < 0.5
    found = achieved_margins(means, variances, enabled, has_receding, has_horizon)
    expected = [combined_margin(means[row], variances[row], enabled[row], has_receding,
                                has_horizon) for row in range(count)]
    np.testing.assert_allclose(found, expected, rtol=1e-14, atol=0.0)
    # From ray polynomials: the same at each link's t, the polynomials evaluated by numpy.
    links = 60
    mean_rows = rng.normal(size=(3, links, conditions))
    variance_rows = rng.normal(size=(5, links, conditions))
    variance_rows[0] = np.abs(variance_rows[0]) + 1.0
    chosen = rng.integers(0, links, size=25)
    t = rng.uniform(0.0, 1.0, size=25)
    found = link_margins(mean_rows, variance_rows, chosen, t, enabled[:25], has_receding,
                         has_horizon)
    expected = [combined_margin(
        [polynomial.polyval(t[index], mean_rows[:, link, condition])
         for condition in range(conditions)],
        [polynomial.polyval(t[index], variance_rows[:, link, condition])
         for condition in range(conditions)], enabled[index], has_receding, has_horizon)
        for index, link in enumerate(chosen)]
    np.testing.assert_allclose(found, expected, rtol=1e-12, atol=0.0)
