"""Measure (and report, without requiring equality) the Taylor solver's error vs the exact one."""

import numpy as np
from prvo_core_testing import random_covariance, random_two_robot_encounter

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.encounter import build_encounter, candidate_directions, condition_layout
from prvo_planner.core.feasibility import achieved_margins, ray_gaps
from prvo_planner.core.moments import condition_moments, ray_polynomials


def membership(gap_direction, lower, upper, directions, t):
    """Boolean (M, T): whether each grid speed of each ray is in a feasible interval."""
    inside = np.zeros((directions, t.size), dtype=bool)
    for direction, low, high in zip(gap_direction, lower, upper, strict=True):
        inside[direction] |= (t >= low) & (t <= high)
    return inside


def test_taylor_error_against_exact_is_measured(record_property):
    rng = np.random.default_rng(31)
    t = np.linspace(0.0, 1.0, 4001)
    config = PlannerConfig(eta=0.8, num_directions=32, actuation_cov=0.01 * np.eye(2))
    differing, rays, difference, unsafe_share = 0, 0, [], []
    velocity_error, exact_k_at_taylor = [], []
    for _ in range(60):
        ego, neighbour = random_two_robot_encounter(rng, 0.15, 0.15)
        neighbours = [neighbour]
        if rng.uniform() < 0.5:
            neighbours.append(AgentBelief(rng.uniform(-4.0, 4.0, 2) + [4.0, 0.0],
                                          rng.uniform(-1.0, 1.0, 2),
                                          random_covariance(rng, 4, 0.15), 0.3))
        v_pref = neighbour.position / np.hypot(*neighbour.position)
        encounter = build_encounter(ego, neighbours, config)
        layout = condition_layout(encounter, config)
        directions = candidate_directions(ego, v_pref, config)
        preferred = directions @ v_pref / config.max_speed
        means, variances = ray_polynomials(encounter.origin, encounter.cov,
                                           encounter.combined_radius, directions,
                                           config.max_speed, config.time_horizon,
                                           layout.has_receding)
        sets = {}
        for method in ('exact', 'taylor'):
            gaps = ray_gaps(means, variances, layout.margins(encounter), layout, method, False,
                            preferred)
            sets[method] = membership(*gaps, directions.shape[0], t)
        mismatch = sets['exact'] != sets['taylor']
        spacing = config.max_speed * (t[1] - t[0])
        rays += directions.shape[0]
        differing += int(np.count_nonzero(np.sum(mismatch, axis=1) > 1))
        difference.extend(spacing * np.sum(mismatch, axis=1))
        unsafe_share.append(np.mean(sets['taylor'] & ~sets['exact']))
        exact = plan_velocity(ego, neighbours, v_pref, config)
        taylor = plan_velocity(ego, neighbours, v_pref,
                               PlannerConfig(eta=0.8, num_directions=32, method='taylor',
                                             actuation_cov=config.actuation_cov))
        velocity_error.append(np.linalg.norm(exact.velocity - taylor.velocity))
        moments = condition_moments(encounter.origin, encounter.cov, encounter.combined_radius,
                                    taylor.velocity[None, :], config.time_horizon,
                                    layout.has_receding)
        exact_k_at_taylor.append(np.min(achieved_margins(moments[0][:, 0], moments[1][:, 0],
                                                         layout, layout.receding_enabled)))
    difference = np.array(difference)
    exact_k_at_taylor = np.array(exact_k_at_taylor)
    report = {
        'rays': rays,
        'rays_with_different_sets': differing / rays,
        'mean_set_difference_m_per_s': float(difference.mean()),
        'max_set_difference_m_per_s': float(difference.max()),
        'share_of_speeds_taylor_accepts_exact_rejects': float(np.mean(unsafe_share)),
        'mean_chosen_velocity_difference_m_per_s': float(np.mean(velocity_error)),
        'max_chosen_velocity_difference_m_per_s': float(np.max(velocity_error)),
        'taylor_plans_below_k_in_exact_terms': float(np.mean(exact_k_at_taylor < 2.0 - 1e-6)),
        'min_exact_k_at_taylor_velocity': float(exact_k_at_taylor.min()),
    }
    for name, value in report.items():
        record_property(name, value)
    print('\nTaylor vs exact:', ', '.join(f'{name}={value:.4g}' for name, value in
                                          report.items()))
    # A measurement, not an equality: only require that it measured something meaningful.
    assert rays > 1000 and np.all(np.isfinite(difference))
