"""The compiled choice cost and best speeds against closed forms and a dense grid."""

import math

import numpy as np

from prvo_planner.core.choice import CostTerms, best_speeds


def closed_form_cost(velocity, v_pref, previous, inertia, bias, progress):
    """Return the choice cost of docs/method.md, section 7, in v_pref's frame (by angles)."""
    speed = math.hypot(*v_pref)
    heading = math.atan2(v_pref[1], v_pref[0])
    angle = math.atan2(velocity[1], velocity[0]) - heading
    magnitude = math.hypot(*velocity)
    along, left = magnitude * math.cos(angle), magnitude * math.sin(angle)
    return ((1.0 - progress) * math.dist(velocity, v_pref)
            + inertia * math.dist(velocity, previous)
            + bias * max(left, 0.0) + progress * abs(speed - along))


def random_terms(rng, count):
    """COUNT plans' cost terms (every term on), as (v_pref, previous, inertia, bias, progress)."""
    return [(rng.uniform(-1.0, 1.0, 2), rng.uniform(-1.0, 1.0, 2), rng.uniform(0.0, 1.5),
             rng.uniform(0.0, 1.0), rng.uniform(0.0, 0.9)) for _ in range(count)]


def cost_terms(v_pref, previous, inertia, bias, progress):
    """Return the CostTerms of one plan with every term on."""
    return CostTerms(table=np.array([[*v_pref, *previous, inertia, bias, progress,
                                      np.hypot(*v_pref)]]), extra=np.array([True]))


def test_the_compiled_cost_is_the_closed_form_for_one_plan_and_for_stacked_rows():
    rng = np.random.default_rng(4)
    plans = random_terms(rng, 6)
    velocities = rng.uniform(-1.5, 1.5, (6, 7, 2))
    for plan, points in zip(plans, velocities, strict=True):
        # One plan's terms against a (7, 2) and a (7, 1, 2) array.
        assert cost_terms(*plan).costs(points[:, None]).shape == (7, 1)
        costs = cost_terms(*plan).costs(points)
        assert costs.shape == (7,)
        for point, cost in zip(points, costs, strict=True):
            assert abs(cost - closed_form_cost(point, *plan)) <= 1e-12
    stacked = CostTerms.stacked([cost_terms(*plan) for plan in plans], np.arange(6))
    # One row of terms per run of velocities: (6, 7, 2) -> (6, 7).
    costs = stacked.costs(velocities)
    assert costs.shape == (6, 7)
    for plan, points, row in zip(plans, velocities, costs, strict=True):
        for point, cost in zip(points, row, strict=True):
            assert abs(cost - closed_form_cost(point, *plan)) <= 1e-12


def test_best_speeds_find_each_plan_s_cheapest_velocity_on_its_intervals():
    rng = np.random.default_rng(7)
    plans = random_terms(rng, 5)
    robot = np.repeat(np.arange(5), [1, 3, 4, 6, 2])
    angles = rng.uniform(-math.pi, math.pi, robot.size)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    lower = rng.uniform(0.0, 0.6, robot.size)
    upper = lower + rng.uniform(0.0, 0.4, robot.size)
    preferred = rng.uniform(-0.2, 1.2, robot.size)
    max_speed = np.array([0.8, 1.0, 1.2, 1.0, 0.5])[robot]
    stacked = CostTerms.stacked([cost_terms(*plan) for plan in plans], robot)
    best = best_speeds(directions, lower, upper, preferred, stacked, max_speed, robot)
    assert np.all((lower <= best) & (best <= upper))
    grid = np.linspace(0.0, 1.0, 20001)
    for index, plan in enumerate(plans):
        rows = np.flatnonzero(robot == index)
        found = min(closed_form_cost(max_speed[row] * best[row] * directions[row], *plan)
                    for row in rows)
        dense = min(closed_form_cost(max_speed[row] * t * directions[row], *plan)
                    for row in rows for t in lower[row] + (upper[row] - lower[row]) * grid)
        # The zoomed grid reaches 3e-5 of an interval, the dense one 5e-5.
        assert abs(found - dense) <= 1e-4


def test_under_the_plain_cost_the_best_speed_is_the_preferred_one_projected():
    rng = np.random.default_rng(9)
    lower = rng.uniform(0.0, 0.5, 12)
    upper = lower + rng.uniform(0.0, 0.5, 12)
    preferred = rng.uniform(-0.5, 1.5, 12)
    one = CostTerms(table=np.array([[1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]]),
                    extra=np.array([False]))
    plain = CostTerms.stacked([one], np.zeros(12, dtype=int))
    angles = rng.uniform(-math.pi, math.pi, 12)
    best = best_speeds(np.stack([np.cos(angles), np.sin(angles)], axis=1), lower, upper,
                       preferred, plain, np.ones(12), np.zeros(12, dtype=int))
    assert np.array_equal(best, np.minimum(np.maximum(preferred, lower), upper))
