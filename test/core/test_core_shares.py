"""The neighbour's share of the avoidance: the relative velocity ``w``, its moments, its bound."""

import dataclasses

import numpy as np
from prvo_core_testing import random_covariance
import pytest

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.encounter import build_encounter
from prvo_planner.core.moments import condition_moments

# Probabilists' Gauss-Hermite rule: 5 nodes per axis integrate polynomials of degree <= 9.
_NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(5)
_GRID = np.stack(np.meshgrid(*[_NODES] * 4, indexing='ij'), axis=-1).reshape(-1, 4)
_GRID_WEIGHTS = np.prod(np.stack(np.meshgrid(*[_WEIGHTS] * 4, indexing='ij'), axis=-1)
                        .reshape(-1, 4), axis=1) / np.sqrt(2.0 * np.pi) ** 4
SHARES = (0.0, 0.25, 0.5, 0.75, 0.9)


def relative_gaussian(ego, neighbour, command, actuation_cov):
    """Mean and covariance of ``z = (r, w)`` as a linear map of the independent variables.

    ``x = (p_i, v_i, p_j, v_j, eps)``; ``r = p_i - p_j``, ``w = (v_c + eps - (1 - rho) v_i) /
    rho - v_j`` with ``rho = 1 - a_j``: written from the definition, not from the planner's
    formulae.
    """
    rho = 1.0 - neighbour.avoidance_share
    mean_x = np.concatenate([ego.position, ego.velocity, neighbour.position,
                             neighbour.velocity, np.zeros(2)])
    cov_x = np.zeros((10, 10))
    cov_x[:4, :4] = ego.covariance
    cov_x[4:8, 4:8] = neighbour.covariance
    cov_x[8:, 8:] = actuation_cov
    identity = np.eye(2)
    linear = np.zeros((4, 10))
    linear[:2, 0:2], linear[:2, 4:6] = identity, -identity
    linear[2:, 2:4] = -(1.0 - rho) / rho * identity
    linear[2:, 6:8] = -identity
    linear[2:, 8:10] = identity / rho
    offset = np.concatenate([np.zeros(2), np.asarray(command) / rho])
    return linear @ mean_x + offset, linear @ cov_x @ linear.T


def condition_values(z, radius, tau, weight):
    """``f``, ``g``, ``h1``, ``h2``, ``h3`` (of WEIGHT) of samples ``z`` (..., 4) by definition."""
    r, w = z[..., :2], z[..., 2:]
    cross = r[..., 0] * w[..., 1] - r[..., 1] * w[..., 0]
    dot = np.sum(r * w, axis=-1)
    speed_sq = np.sum(w * w, axis=-1)
    reach = r + tau * w
    distance_sq = np.sum(r * r, axis=-1)
    return np.stack([cross ** 2 - radius ** 2 * speed_sq, dot, -dot - tau * speed_sq,
                     np.sum(reach * reach, axis=-1) - radius ** 2,
                     (1.0 - weight) * (distance_sq - tau ** 2 * speed_sq / weight)
                     - radius ** 2], axis=-1)


def random_pair(rng, share):
    ego = AgentBelief(rng.normal(size=2), rng.normal(size=2),
                      random_covariance(rng, 4, rng.uniform(0.05, 0.4)), 0.3)
    neighbour = AgentBelief(rng.uniform(2.0, 5.0, size=2), rng.normal(size=2),
                            random_covariance(rng, 4, rng.uniform(0.05, 0.4)),
                            rng.uniform(0.2, 0.8), share)
    return ego, neighbour


@pytest.mark.parametrize('share', SHARES)
def test_condition_moments_of_every_share_match_quadrature(share):
    rng = np.random.default_rng(int(share * 100) + 7)
    tau = 3.0
    for _ in range(20):
        ego, neighbour = random_pair(rng, share)
        actuation_cov = random_covariance(rng, 2, rng.uniform(0.02, 0.3))
        config = PlannerConfig(actuation_cov=actuation_cov, neighbor_distance=100.0)
        encounter = build_encounter(ego, [neighbour], config)
        command = rng.normal(size=2)
        means, variances = condition_moments(
            encounter.origin, encounter.cov, encounter.combined_radius, command[None, :], tau,
            True, encounter.lead)
        mean_z, cov_z = relative_gaussian(ego, neighbour, command, actuation_cov)
        eigenvalues, eigenvectors = np.linalg.eigh(cov_z)
        nodes = mean_z + _GRID @ (eigenvectors * np.sqrt(np.maximum(eigenvalues, 0.0))).T
        # h3's weight: 1 - R / |mean r|, within [0.05, 0.95].
        radius = encounter.combined_radius[0]
        weight = min(max(1.0 - radius / np.hypot(*mean_z[:2]), 0.05), 0.95)
        values = condition_values(nodes, radius, tau, weight)
        first = _GRID_WEIGHTS @ values
        second = _GRID_WEIGHTS @ values ** 2
        np.testing.assert_allclose(means[0, 0], first, rtol=0.0, atol=1e-9 * np.sqrt(second).max())
        np.testing.assert_allclose(variances[0, 0], second - first ** 2, rtol=0.0,
                                   atol=1e-9 * second.max())


def test_share_one_half_is_the_reciprocal_encounter_bit_for_bit():
    rng = np.random.default_rng(31)
    config = PlannerConfig(actuation_cov=random_covariance(rng, 2, 0.1), neighbor_distance=100.0)
    ego, neighbour = random_pair(rng, 0.5)
    encounter = build_encounter(ego, [neighbour], config)
    # u = 2 v_x - v_i - v_j: the paper's relative velocity, written out.
    np.testing.assert_array_equal(encounter.origin[0, 2:], -ego.velocity - neighbour.velocity)
    np.testing.assert_array_equal(
        encounter.cov[0, 2:, 2:], 4.0 * config.actuation_cov + ego.covariance[2:, 2:]
        + neighbour.covariance[2:, 2:])
    np.testing.assert_array_equal(encounter.cov[0, :2, 2:],
                                  -ego.covariance[:2, 2:] + neighbour.covariance[:2, 2:])
    assert encounter.lead.tolist() == [2.0]


def test_share_zero_is_the_velocity_obstacle():
    rng = np.random.default_rng(32)
    config = PlannerConfig(actuation_cov=random_covariance(rng, 2, 0.1), neighbor_distance=100.0)
    ego, neighbour = random_pair(rng, 0.0)
    encounter = build_encounter(ego, [neighbour], config)
    # w = v_x - v_j: the ego's own velocity estimate drops out, its noise enters once.
    np.testing.assert_array_equal(encounter.origin[0, 2:], -neighbour.velocity)
    np.testing.assert_allclose(encounter.cov[0, 2:, 2:],
                               config.actuation_cov + neighbour.covariance[2:, 2:], atol=1e-15)
    np.testing.assert_allclose(encounter.cov[0, :2, 2:], neighbour.covariance[:2, 2:],
                               atol=1e-15)
    assert encounter.lead.tolist() == [1.0]


def crossing(share, rng):
    """Ego heading east to its goal; a neighbour crossing its path from the south."""
    ego = AgentBelief([0.0, 0.0], [1.0, 0.0], np.diag([0.004, 0.004, 0.01, 0.01]), 0.3)
    neighbour = AgentBelief([2.5, -2.3], [0.0, 1.0] + rng.normal(0.0, 0.02, 2),
                            np.diag([0.004, 0.004, 0.01, 0.01]), 0.5, share)
    return ego, neighbour


def no_contact_probability(ego, neighbour, command, actuation_cov, tau, samples, rng):
    """P(the real motion keeps the pair apart for tau s), the neighbour keeping its velocity.

    Sampled from the beliefs and the noise; the real relative velocity is ``v_x - v_j``.
    """
    ego_states = rng.multivariate_normal(np.r_[ego.position, ego.velocity], ego.covariance,
                                         samples)
    other = rng.multivariate_normal(np.r_[neighbour.position, neighbour.velocity],
                                    neighbour.covariance, samples)
    executed = command + rng.multivariate_normal(np.zeros(2), actuation_cov, samples)
    r, u = ego_states[:, :2] - other[:, :2], executed - other[:, 2:]
    closest = np.clip(-np.sum(r * u, axis=1) / np.maximum(np.sum(u * u, axis=1), 1e-300), 0.0,
                      tau)
    gap = np.linalg.norm(r + closest[:, None] * u, axis=1)
    return float(np.mean(gap >= ego.radius + neighbour.radius))


def plan_crossing(share, eta, rng):
    """Plan the ego of ``crossing`` with the neighbour's share ``share``; return the pieces."""
    actuation_cov = 0.0025 * np.eye(2)
    config = PlannerConfig(eta=eta, max_speed=1.0, actuation_cov=actuation_cov,
                           time_horizon=5.0, inertia=0.0, passing_bias=0.0)
    ego, neighbour = crossing(0.0, rng)
    result = plan_velocity(ego, [dataclasses.replace(neighbour, avoidance_share=share)],
                           np.array([1.0, 0.0]), config)
    return ego, neighbour, result, actuation_cov


@pytest.mark.parametrize('eta', [0.7, 0.8, 0.9])
def test_cantelli_bound_holds_against_a_neighbour_that_does_not_avoid(eta):
    rng = np.random.default_rng(41)
    ego, neighbour, result, actuation_cov = plan_crossing(0.0, eta, rng)
    assert result.feasible
    assert no_contact_probability(ego, neighbour, result.velocity, actuation_cov, 5.0, 200_000,
                                  rng) >= eta


def test_assuming_half_of_a_neighbour_that_does_not_avoid_breaks_the_bound():
    # Planned as if the neighbour took half, the ego leaves it half the clearance.
    rng = np.random.default_rng(41)
    ego, neighbour, result, actuation_cov = plan_crossing(0.5, 0.7, rng)
    assert result.feasible
    # Measured 0.58 (0.96 planned with the true share), 200000 samples: standard error 0.001.
    assert no_contact_probability(ego, neighbour, result.velocity, actuation_cov, 5.0, 200_000,
                                  rng) < 0.7


@pytest.mark.parametrize('share', [-0.1, 1.0, 1.5, float('nan'), '0.5', None])
def test_a_share_outside_zero_one_is_refused_naming_the_field(share):
    with pytest.raises(ValueError, match=r'^AgentBelief\.avoidance_share must be'):
        AgentBelief([0.0, 0.0], [0.0, 0.0], np.eye(4), 0.3, share)



def near_pair(share, offset, velocity):
    """Ego heading east; a neighbour of SHARE at OFFSET (gap 0.1-0.3 m) moving at VELOCITY."""
    covariance = 0.0025 * np.eye(4)
    return (AgentBelief([0.0, 0.0], [1.0, 0.0], covariance, 0.3),
            AgentBelief(offset, velocity, covariance, 0.3, share))


def test_a_guard_row_is_the_velocity_obstacle_over_the_guard_time():
    rng = np.random.default_rng(51)
    config = PlannerConfig(actuation_cov=random_covariance(rng, 2, 0.1), time_horizon=2.0,
                           guard_time=0.5)
    ego, near = near_pair(0.5, [0.5, -0.7], [0.0, 0.6])
    # 0.9 m apart, beyond reach: within 0.5 s the two close by at most 0.5 (1.0 + 0.6) m.
    far = AgentBelief([1.5, 0.0], [-0.6, 0.0], 0.0025 * np.eye(4), 0.3, 0.5)
    standing = dataclasses.replace(near, position=np.array([-0.5, 0.7]), avoidance_share=0.0)
    guarded = build_encounter(ego, [far, near, standing], config)
    unguarded = build_encounter(ego, [far, near, standing],
                                dataclasses.replace(config, guard_time=0.0))
    plain = build_encounter(ego, [dataclasses.replace(near, avoidance_share=0.0)],
                            dataclasses.replace(config, guard_time=0.0))
    # Every neighbour as announced, in order, then the near one that avoids, as if it did not.
    for name in ('origin', 'cov', 'lead', 'combined_radius', 'overlapping'):
        np.testing.assert_array_equal(getattr(guarded, name)[:3], getattr(unguarded, name))
    assert guarded.margin == unguarded.margin
    # Its w scaled by 0.5 / 2: contact within 2 s along it is contact within 0.5 s along w.
    scale = np.diag([1.0, 1.0, 0.25, 0.25])
    np.testing.assert_allclose(guarded.origin[3], scale @ plain.origin[0], atol=1e-15)
    np.testing.assert_allclose(guarded.cov[3], scale @ plain.cov[0] @ scale, atol=1e-15)
    assert guarded.lead.tolist() == [2.0, 2.0, 1.0, 0.25]
    command = np.array([0.4, 0.7])
    for tau, encounter, row in ((2.0, guarded, 3), (0.5, plain, 0)):
        means, variances = condition_moments(
            encounter.origin[row:row + 1], encounter.cov[row:row + 1],
            encounter.combined_radius[row:row + 1], command[None, :], tau, True,
            encounter.lead[row:row + 1])
        margin = (means / np.sqrt(variances)).ravel()
        if tau == 2.0:
            guard_margin = margin
    # The same margin of every condition: each scales as a whole, its sign kept.
    np.testing.assert_allclose(guard_margin, margin, rtol=1e-9)


def test_a_guard_row_shares_the_joint_risk():
    config = PlannerConfig(eta=0.9, risk='joint', guard_time=0.5)
    ego, near = near_pair(0.5, [0.5, -0.7], [0.0, 0.6])
    # Two conditions share 1 - eta: each is held at 1 - 0.1 / 2.
    assert build_encounter(ego, [near], config).eta == pytest.approx(0.95)


@pytest.mark.parametrize('certificate', ['cantelli', 'certified'])
@pytest.mark.parametrize('offset, velocity', [([0.5, -0.7], [0.0, 0.6]),
                                              ([0.6, -0.6], [-0.3, 0.6]),
                                              ([0.8, 0.2], [-0.8, 0.0]),
                                              ([0.75, -0.35], [-0.5, 0.5])])
def test_near_contact_the_guard_holds_eta_if_the_neighbour_keeps_its_velocity(
        certificate, offset, velocity):
    # The neighbour announces that it reciprocates, and keeps its velocity: without the guard
    # the plan keeps 0.007-0.68 of such pairs apart over the guard's 0.5 s (measured, eta 0.8),
    # with it 0.84-0.996.
    actuation_cov = 0.0025 * np.eye(2)
    ego, neighbour = near_pair(0.5, offset, velocity)
    rng = np.random.default_rng(52)
    guarded = PlannerConfig(eta=0.8, actuation_cov=actuation_cov, time_horizon=2.0,
                            certificate=certificate, guard_time=0.5)
    for config, holds in ((guarded, True),
                          (dataclasses.replace(guarded, guard_time=0.0), False)):
        result = plan_velocity(ego, [neighbour], np.array([1.0, 0.0]), config)
        assert result.feasible
        # 100000 samples: standard error 0.0013 at 0.8.
        kept_apart = no_contact_probability(ego, neighbour, result.velocity, actuation_cov,
                                            0.5, 100_000, rng)
        assert (kept_apart >= 0.8) == holds, (config.guard_time, kept_apart)


@pytest.mark.parametrize('guard', [-0.1, float('nan'), float('inf'), '0.3', True])
def test_a_guard_time_that_is_not_finite_and_positive_is_refused_naming_the_field(guard):
    with pytest.raises(ValueError, match=r'^PlannerConfig\.guard_time must be'):
        PlannerConfig(guard_time=guard)


def test_the_encounter_keeps_the_neighbours_within_reach_as_their_relative_gaussians():
    rng = np.random.default_rng(61)
    actuation_cov = random_covariance(rng, 2, 0.2)
    config = PlannerConfig(actuation_cov=actuation_cov, neighbor_distance=3.0,
                           safety_margin=0.05)
    ego = AgentBelief(rng.normal(size=2), rng.normal(size=2), random_covariance(rng, 4, 0.3),
                      0.3)
    neighbours = [AgentBelief(ego.position + rng.uniform(-6.0, 6.0, size=2), rng.normal(size=2),
                              random_covariance(rng, 4, rng.uniform(0.05, 0.4)),
                              rng.uniform(0.2, 0.5), rng.choice(SHARES)) for _ in range(12)]
    encounter = build_encounter(ego, neighbours, config)
    # Kept: the gap between the mean disks at most neighbor_distance, in order.
    kept = [neighbour for neighbour in neighbours if np.hypot(*(
        ego.position - neighbour.position)) - ego.radius - neighbour.radius <= 3.0]
    assert 0 < len(kept) < len(neighbours)
    assert encounter.origin.shape == (len(kept), 4)
    for row, neighbour in enumerate(kept):
        mean_z, cov_z = relative_gaussian(ego, neighbour, np.zeros(2), actuation_cov)
        np.testing.assert_allclose(encounter.origin[row], mean_z, rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(encounter.cov[row], cov_z, rtol=0.0, atol=1e-12)
        assert encounter.lead[row] == pytest.approx(1.0 / (1.0 - neighbour.avoidance_share),
                                                    rel=1e-15)
        radius = ego.radius + neighbour.radius + 0.05
        assert encounter.combined_radius[row] == pytest.approx(radius, rel=1e-15)
        assert encounter.overlapping[row] == (np.hypot(*mean_z[:2]) < radius)
    empty = build_encounter(ego, [], config)
    assert empty.origin.shape == (0, 4) and empty.cov.shape == (0, 4, 4)
