"""The probabilistic guarantees, checked by sampling the beliefs (docs/method.md 5 and 7)."""

import math

from independent import line_clear, relative_samples
import numpy as np
from prvo_core_testing import random_two_robot_encounter
import pytest

from prvo_planner.core import PlannerConfig, eta_from_k, plan_velocity

SAMPLES = 4000
# One-sided z for a family-wise false alarm below 1e-3 over the ~1000 checks of this module.
Z = 4.8


@pytest.mark.parametrize('k', [1.0, 1.5, 2.0, 3.0])
def test_cantelli_bound_holds_at_the_chosen_velocity(k):
    rng = np.random.default_rng(int(10 * k))
    bound = eta_from_k(k)
    feasible = active = 0
    lowest = 1.0
    for _ in range(200):
        ego, neighbour = random_two_robot_encounter(rng)
        actuation = np.diag(rng.uniform(0.0, 0.03, size=2))
        config = PlannerConfig(k=k, receding_gate=False, time_horizon=math.inf,
                               num_directions=32, max_speed=1.2, actuation_cov=actuation)
        # Prefer heading at the neighbour so that the constraint is usually active.
        v_pref = neighbour.position / np.hypot(*neighbour.position) + rng.normal(0.0, 0.2, 2)
        result = plan_velocity(ego, [neighbour], v_pref, config)
        if not result.feasible:
            continue
        feasible += 1
        active += result.achieved_k < k + 1e-3
        r, u = relative_samples(rng, ego, neighbour, result.velocity, actuation, SAMPLES)
        probability = np.mean(line_clear(r, u, ego.radius + neighbour.radius))
        lowest = min(lowest, probability)
        assert probability >= bound - Z * math.sqrt(bound * (1.0 - bound) / SAMPLES)
    print(f'k={k}: {feasible}/200 feasible, {active} active, lowest sampled P = {lowest:.3f} '
          f'>= {bound:.3f}')
    # The constraint binds (the chosen velocity sits on the surrogate boundary) in many cases.
    assert feasible >= 150 and active >= 25


@pytest.mark.parametrize('eta', [0.6, 0.8, 0.9])
def test_horizon_plan_is_safe_within_the_horizon_with_probability_eta(eta):
    rng = np.random.default_rng(int(100 * eta))
    tau = 4.0
    feasible = 0
    for _ in range(40):
        ego, first = random_two_robot_encounter(rng)
        _, second = random_two_robot_encounter(rng)
        neighbours = [first, second]
        actuation = np.diag(rng.uniform(0.0, 0.02, size=2))
        config = PlannerConfig(eta=eta, time_horizon=tau, receding_gate=True, num_directions=32,
                               actuation_cov=actuation)
        v_pref = first.position / np.hypot(*first.position)
        result = plan_velocity(ego, neighbours, v_pref, config)
        if not result.feasible:
            continue
        feasible += 1
        for neighbour in neighbours:
            position, velocity = relative_samples(rng, ego, neighbour, result.velocity,
                                                  actuation, SAMPLES)
            # Simulate r(t) = r + t u on [0, tau]: safe if the motion never brings the robots
            # closer than R, or closer than they already are.
            speed_sq = np.sum(velocity ** 2, axis=1)
            closest = np.clip(-np.sum(position * velocity, axis=1) / np.maximum(speed_sq, 1e-300),
                              0.0, tau)
            distance_sq = np.sum((position + closest[:, None] * velocity) ** 2, axis=1)
            radius_sq = (ego.radius + neighbour.radius) ** 2
            safe = distance_sq >= np.minimum(radius_sq, np.sum(position ** 2, axis=1)) - 1e-12
            assert safe.mean() >= eta - Z * math.sqrt(eta * (1.0 - eta) / SAMPLES)
    assert feasible >= 20
