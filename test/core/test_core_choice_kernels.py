"""The compiled choice cost and the cheapest velocities against closed forms and a dense grid."""

import math

import numpy as np

from prvo_planner.core.choice import INTERIOR, CostTerms, cheapest_velocities
from prvo_planner.core.feasibility import RayRows


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


def random_gaps(rng, ray_counts, v_prefs, max_speed):
    """
    Rays of plans (RAY_COUNTS each) and sorted, disjoint feasible intervals on some of them.

    A ray's preferred ``t`` is its plan's ``v_pref`` (V_PREFS) projected on it, over MAX_SPEED.
    """
    ray_robot = np.repeat(np.arange(len(ray_counts)), ray_counts)
    ray_local = np.concatenate([np.arange(count) for count in ray_counts])
    angles = rng.uniform(-math.pi, math.pi, ray_robot.size)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    gap_ray, lower, upper = [], [], []
    for ray in range(ray_robot.size):
        # 0-3 intervals: sorted cut points of [0, 1], every other span kept.
        cuts = np.sort(rng.uniform(0.0, 1.0, 2 * rng.integers(0, 4)))
        for start, stop in cuts.reshape(-1, 2):
            gap_ray.append(ray)
            lower.append(start)
            upper.append(stop)
    rows = RayRows(means=np.zeros((0, 1, 3)), variances=np.zeros((0, 1, 5)),
                   margins=np.zeros((0, 1)), link_ray=np.zeros(0, dtype=int),
                   link_enabled=np.zeros(0, dtype=bool), ray_local=ray_local,
                   ray_robot=ray_robot,
                   preferred=np.sum(directions * np.asarray(v_prefs)[ray_robot], axis=1)
                   / np.asarray(max_speed)[ray_robot])
    return (np.array(gap_ray, dtype=np.int64), np.array(lower), np.array(upper), directions,
            rows)


def test_the_cheapest_velocities_are_each_plan_s_cheapest_on_its_intervals():
    rng = np.random.default_rng(7)
    plans = random_terms(rng, 5)
    max_speed = np.array([0.8, 1.0, 1.2, 1.0, 0.5])
    gap_ray, lower, upper, directions, rows = random_gaps(
        rng, [3, 6, 1, 8, 5], [plan[0] for plan in plans], max_speed)
    stacked = CostTerms.stacked([cost_terms(*plan) for plan in plans], np.arange(5))
    feasible_rays, direction, chosen = cheapest_velocities(gap_ray, lower, upper, directions,
                                                           rows, stacked, max_speed)
    grid = np.linspace(0.0, 1.0, 20001)
    for index, plan in enumerate(plans):
        own = np.flatnonzero(rows.ray_robot[gap_ray] == index)
        assert feasible_rays[index] == len(set(gap_ray[own].tolist()))
        if not own.size:
            assert direction[index] == -1
            continue
        ray = np.flatnonzero((rows.ray_robot == index) & (rows.ray_local == direction[index]))[0]
        # The chosen t lies inside one of the chosen ray's intervals, INTERIOR from its ends.
        assert np.any((gap_ray == ray) & (lower + INTERIOR * 0.99 <= chosen[index])
                      & (chosen[index] <= upper - INTERIOR * 0.99)
                      | (gap_ray == ray) & (upper - lower <= 2.0 * INTERIOR))
        found = closed_form_cost(max_speed[index] * chosen[index] * directions[ray], *plan)
        dense = min(closed_form_cost(max_speed[index] * t * directions[gap_ray[gap]], *plan)
                    for gap in own for t in lower[gap] + (upper[gap] - lower[gap]) * grid)
        # The zoomed grid reaches 3e-5 of an interval, the dense one 5e-5.
        assert abs(found - dense) <= 1e-4


def test_under_the_plain_cost_the_cheapest_velocity_is_the_nearest_projection():
    rng = np.random.default_rng(9)
    v_pref = np.array([0.6, -0.3])
    gap_ray, lower, upper, directions, rows = random_gaps(rng, [12], [v_pref], [1.0])
    plain = CostTerms(table=np.array([[*v_pref, *v_pref, 0.0, 0.0, 0.0, 1.0]]),
                      extra=np.array([False]))
    _, direction, chosen = cheapest_velocities(gap_ray, lower, upper, directions, rows, plain,
                                               np.ones(1))
    # Under |v - v_pref| the best t of a ray is v_pref's projection clipped to the interval.
    projected = np.clip(rows.preferred[gap_ray], lower + INTERIOR, upper - INTERIOR)
    costs = np.hypot(*(projected[:, None] * directions[gap_ray] - v_pref).T)
    best = int(np.argmin(costs))
    assert direction[0] == rows.ray_local[gap_ray[best]]
    assert chosen[0] == projected[best]
