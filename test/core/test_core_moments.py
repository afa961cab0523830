"""``rvo_moments`` and the ray polynomials against quadrature and Monte Carlo."""

import math

from independent import rvo_f
import numpy as np
from prvo_core_testing import random_covariance
import pytest

from prvo_planner.core import rvo_moments
from prvo_planner.core.moments import (
    bivariate_polynomials,
    condition_margins,
    condition_moments,
    ray_polynomials,
    reach_weights,
)

# Probabilists' Gauss-Hermite rule: 5 nodes integrate polynomials of degree <= 9 exactly.
_NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(5)
_GRID = np.stack(np.meshgrid(*[_NODES] * 4, indexing='ij'), axis=-1).reshape(-1, 4)
_GRID_WEIGHTS = np.prod(np.stack(np.meshgrid(*[_WEIGHTS] * 4, indexing='ij'), axis=-1)
                        .reshape(-1, 4), axis=1) / np.sqrt(2.0 * np.pi) ** 4


def quadrature_values(function, mean, cov):
    """
    Evaluate ``function`` at the 625 tensor Gauss-Hermite nodes of ``N(mean, cov)``.

    ``np.sum(_GRID_WEIGHTS * values)`` is then ``E[function(z)]`` exactly for polynomials of
    degree <= 9 in each coordinate (``f`` and ``f^2`` have degree <= 8).

    """
    eigenvalues, eigenvectors = np.linalg.eigh(cov)
    root = eigenvectors * np.sqrt(np.maximum(eigenvalues, 0.0))
    return function(mean + _GRID @ root.T)


def random_case(rng):
    """Random mean, full covariance and radius of ``z``."""
    mean = rng.normal(0.0, 2.0, size=4)
    cov = random_covariance(rng, 4, rng.uniform(0.05, 1.0))
    return mean, cov, rng.uniform(0.2, 1.5)


def random_neighbours(rng, count):
    """Return (origin (N, 4), cov (N, 4, 4), radius (N,)) of COUNT random cases.

    Each origin is its case's mean with half its relative velocity (a command of half of it).
    """
    cases = [random_case(rng) for _ in range(count)]
    origin = np.array([np.r_[mean[:2], 0.5 * mean[2:]] for mean, _, _ in cases])
    return origin, np.array([case[1] for case in cases]), np.array([case[2] for case in cases])


def written_conditions(big_r, tau=None, eps=None, gate=True):
    """
    Return the conditions' functions of z (P, 4), written from their definitions.

    ``f``; ``g`` where GATE; with a finite TAU the horizon pair ``h1``, ``h2``; and with EPS too
    the lead's condition.
    """
    conditions = [lambda z: rvo_f(z[..., :2], z[..., 2:], big_r)]
    if gate:
        conditions.append(lambda z: np.sum(z[:, :2] * z[:, 2:], axis=1))
    if tau is None:
        return conditions
    conditions += [
        lambda z: -np.sum(z[:, :2] * z[:, 2:], axis=1) - tau * np.sum(z[:, 2:] ** 2, axis=1),
        lambda z: np.sum((z[:, :2] + tau * z[:, 2:]) ** 2, axis=1) - big_r ** 2,
    ]
    if eps is not None:
        conditions.append(lambda z: (
            (1.0 - eps) * (np.sum(z[:, :2] ** 2, axis=1)
                           - tau ** 2 / eps * np.sum(z[:, 2:] ** 2, axis=1)) - big_r ** 2))
    return conditions


def test_moments_match_gauss_hermite_quadrature():
    rng = np.random.default_rng(11)
    cases = [random_case(rng) for _ in range(150)]
    means = np.array([case[0] for case in cases])
    covs = np.array([case[1] for case in cases])
    radii = np.array([case[2] for case in cases])
    expectation, variance = rvo_moments(means, covs, radii)
    for index, (mean, cov, radius) in enumerate(cases):
        values = quadrature_values(
            lambda z, radius=radius: rvo_f(z[..., :2], z[..., 2:], radius), mean, cov)
        first = np.sum(_GRID_WEIGHTS * values)
        second = np.sum(_GRID_WEIGHTS * values ** 2)
        reference_variance = second - first ** 2
        # Relative to the natural scale E[f^2] so that near-zero means are not penalised.
        assert abs(expectation[index] - first) <= 1e-9 * np.sqrt(second)
        assert abs(variance[index] - reference_variance) <= 1e-9 * second


def test_moments_match_monte_carlo_within_four_standard_errors():
    rng = np.random.default_rng(12)
    samples = 1_000_000
    for _ in range(3):
        mean, cov, radius = random_case(rng)
        z = rng.multivariate_normal(mean, cov, size=samples)
        values = rvo_f(z[:, :2], z[:, 2:], radius)
        expectation, variance = rvo_moments(mean, cov, radius)
        sample_variance = np.var(values)
        mean_error = np.sqrt(sample_variance / samples)
        variance_error = np.sqrt(np.var((values - values.mean()) ** 2) / samples)
        assert abs(expectation - values.mean()) <= 4.0 * mean_error
        assert abs(variance - sample_variance) <= 4.0 * variance_error


def test_horizon_condition_moments_match_quadrature():
    rng = np.random.default_rng(13)
    tau = 3.0
    for _ in range(30):
        mean, cov, radius = random_case(rng)
        origin = np.r_[mean[:2], 0.0, 0.0][None, :]
        command = 0.5 * mean[2:]
        means, variances = condition_moments(origin, cov[None], np.array([radius]),
                                             command[None, :], tau, True)
        conditions = written_conditions(radius, tau)
        for column, condition in enumerate(conditions):
            values = quadrature_values(condition, mean, cov)
            first = np.sum(_GRID_WEIGHTS * values)
            second = np.sum(_GRID_WEIGHTS * values ** 2)
            assert abs(means[0, 0, column] - first) <= 1e-9 * np.sqrt(second)
            assert abs(variances[0, 0, column] - (second - first ** 2)) <= 1e-9 * second


def test_batched_condition_moments_match_quadrature_per_neighbour_and_command():
    # One call for neighbours of their own horizon, lead and commands, with and without the
    # gate: the compiled moments reuse their work arrays neighbour after neighbour, and each
    # (neighbour, command, condition) must be that neighbour's own integral.
    rng = np.random.default_rng(15)
    count, points = 7, 3
    origin, cov, radius = random_neighbours(rng, count)
    horizon = rng.uniform(0.5, 4.0, size=count)
    lead = rng.uniform(1.0, 2.0, size=count)
    commands = rng.normal(0.0, 1.0, size=(count, points, 2))
    weights = reach_weights(origin, radius)
    for gate in (True, False):
        means, variances = condition_moments(origin, cov, radius, commands, horizon, gate, lead)
        assert means.shape == variances.shape == (count, points, 4 + gate)
        for neighbour in range(count):
            tau, eps, big_r = horizon[neighbour], weights[neighbour], radius[neighbour]
            conditions = written_conditions(big_r, tau, eps, gate)
            for point in range(points):
                mean = origin[neighbour].copy()
                mean[2:] += lead[neighbour] * commands[neighbour, point]
                for column, condition in enumerate(conditions):
                    values = quadrature_values(condition, mean, cov[neighbour])
                    first = np.sum(_GRID_WEIGHTS * values)
                    second = np.sum(_GRID_WEIGHTS * values ** 2)
                    assert abs(means[neighbour, point, column] - first) <= 1e-9 * np.sqrt(second)
                    assert (abs(variances[neighbour, point, column] - (second - first ** 2))
                            <= 1e-9 * second)


def test_ray_polynomials_reproduce_moments_along_rays():
    rng = np.random.default_rng(14)
    count, scale = 6, 1.7
    origin = rng.normal(0.0, 2.0, size=(count, 4))
    cov = np.array([random_covariance(rng, 4, 0.3) for _ in range(count)])
    radius = rng.uniform(0.3, 1.0, size=count)
    angles = rng.uniform(0.0, 2.0 * np.pi, size=9)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    means, variances = ray_polynomials(origin, cov, radius, directions, scale, 4.0, True)
    t = rng.uniform(0.0, 1.0, size=9)
    velocities = scale * t[:, None] * directions
    # Each direction's own velocity through the closed form, one direction at a time.
    for index in range(directions.shape[0]):
        reference_mean, reference_variance = condition_moments(
            origin, cov, radius, velocities[index][None, :], 4.0, True)
        powers = t[index] ** np.arange(5)
        got_mean = means[:, index] @ powers[:3]
        got_variance = variances[:, index] @ powers
        np.testing.assert_allclose(got_mean, reference_mean[:, 0], rtol=1e-9,
                                   atol=1e-9 * np.max(np.abs(reference_mean)))
        np.testing.assert_allclose(got_variance, reference_variance[:, 0], rtol=1e-9,
                                   atol=1e-9 * np.max(np.abs(reference_variance)))


def _reach_weight(origin, radius):
    """``h3``'s weight written from its definition: ``1 - R / |mu_r|`` within [0.05, 0.95]."""
    distance = float(np.hypot(origin[0], origin[1]))
    if distance == 0.0:
        return 0.05
    return min(max(1.0 - radius / distance, 0.05), 0.95)


def test_reach_weights_match_their_definition():
    origin = np.array([[3.0, 4.0, 0.1, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0],
                       [0.3, 0.4, 0.0, 0.0], [100.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]])
    radius = np.array([1.0, 0.5, 0.0, 0.5, 1.0, 0.0])
    expected = [_reach_weight(row, big_r) for row, big_r in zip(origin, radius, strict=True)]
    assert expected == [0.8, 0.05, 0.05, 0.05, 0.95, 0.95]
    np.testing.assert_allclose(reach_weights(origin, radius), expected, rtol=1e-15)


def test_bivariate_polynomials_match_quadrature_off_the_grid():
    # One call for neighbours of their own plan's v_max, horizon and lead, with and without the
    # gate; the fitted quadratic and quartic, evaluated at commands off the grid, must be each
    # neighbour's own integrals there.
    rng = np.random.default_rng(17)
    count = 5
    origin, cov, radius = random_neighbours(rng, count)
    horizon = rng.uniform(0.5, 4.0, size=count)
    lead = rng.uniform(1.0, 2.0, size=count)
    scale = rng.uniform(0.5, 2.0, size=count)
    nodes_1d = np.cos(np.pi * np.arange(5) / 4.0)
    grid = np.array([(x, y) for x in nodes_1d for y in nodes_1d])
    exponents = [(degree - j, j) for degree in range(5) for j in range(degree + 1)]
    for gate in (True, False):
        mean_fit, variance_fit = bivariate_polynomials(
            origin, cov, radius, scale[:, None, None] * grid, horizon, gate, lead)
        assert mean_fit.shape == (count, 4 + gate, 6)
        assert variance_fit.shape == (count, 4 + gate, 15)
        for neighbour in range(count):
            tau, big_r = horizon[neighbour], radius[neighbour]
            eps = _reach_weight(origin[neighbour], big_r)
            conditions = written_conditions(big_r, tau, eps, gate)
            for unit in rng.uniform(-1.0, 1.0, size=(3, 2)):
                monomials = np.array([unit[0] ** i * unit[1] ** j for i, j in exponents])
                mean = origin[neighbour].copy()
                mean[2:] += lead[neighbour] * scale[neighbour] * unit
                for column, condition in enumerate(conditions):
                    values = quadrature_values(condition, mean, cov[neighbour])
                    first = np.sum(_GRID_WEIGHTS * values)
                    second = np.sum(_GRID_WEIGHTS * values ** 2)
                    got_mean = mean_fit[neighbour, column] @ monomials[:6]
                    got_variance = variance_fit[neighbour, column] @ monomials
                    assert abs(got_mean - first) <= 1e-9 * np.sqrt(second)
                    assert abs(got_variance - (second - first ** 2)) <= 1e-9 * second


def test_condition_margins_meet_the_closed_form_of_the_quadrature_moments():
    # The margins of shared commands against each neighbour, from each condition's moments
    # integrated by quadrature and combined condition by condition (docs/method.md, section 7).
    from test_core_ray_search import combined_margin

    rng = np.random.default_rng(19)
    count = 5
    origin, cov, radius = random_neighbours(rng, count)
    lead = rng.uniform(1.0, 2.0, size=count)
    enabled = np.array([True, False, True, True, False])
    commands = rng.normal(0.0, 1.0, size=(2, 2))
    for tau in (2.5, math.inf):
        finite = math.isfinite(tau)
        found = condition_margins(origin, cov, radius, commands, tau, True, lead, enabled)
        assert found.shape == (2, count)
        for neighbour in range(count):
            big_r = radius[neighbour]
            eps = _reach_weight(origin[neighbour], big_r)
            conditions = written_conditions(big_r, tau if finite else None, eps)
            for point, command in enumerate(commands):
                mean = origin[neighbour].copy()
                mean[2:] += lead[neighbour] * command
                moments = []
                for condition in conditions:
                    values = quadrature_values(condition, mean, cov[neighbour])
                    first = np.sum(_GRID_WEIGHTS * values)
                    moments.append((first, np.sum(_GRID_WEIGHTS * values ** 2) - first ** 2))
                expected = combined_margin([m for m, _ in moments], [v for _, v in moments],
                                           enabled[neighbour], True, finite)
                assert found[point, neighbour] == pytest.approx(expected, rel=1e-7, abs=1e-9)
