"""The walls' compiled kernels (core/wall_kernels.py) against independent oracles.

The crossing bound's oracle is the reflection principle's bound written out in mpmath at 50
digits, in its own form (``exp(2 a x0 / walk) Phi(-u)``, not through ``erfcx``), and the largest
accepted speed is that oracle's root found by bisection in mpmath. The rejected intervals are
checked on dense samples of each ray, each speed judged from the definitions of the conditions
and pieces, the parallel tangents' bounds in closed form: nothing of the kernels is reused.
"""

import math

import mpmath
import numpy as np
import pytest
from scipy.stats import norm

from prvo_planner.core import AgentBelief, PlannerConfig, wall_kernels
from prvo_planner.core import walls as walls_module
from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.core.special_kernels import erfcx
from prvo_planner.core.wall_kernels import crossing_bounds, line_speeds
from prvo_planner.core.walls import (
    cut_by_walls,
    obstacle_probability,
    rejected_intervals,
    wall_model,
)

mpmath.mp.dps = 50


def exact_bound(mean0, std0, walk, horizon, approach):
    """``P(min over [0, horizon] of y0 - approach t + W(t) < 0)``'s bound, in mpmath.

    ``y0 ~ N(mean0, std0^2)``, ``W`` a Brownian motion of variance WALK per second. Without a
    walk the first term alone (the path is straight); with one, ``y`` is a Brownian motion
    started at ``x0 = mean0 + approach t0`` at ``-t0 = -std0^2 / walk``, and its first passage
    below 0 by the horizon has the reflection principle's probability; ``x0 <= 0``: 1.
    """
    mean0, std0, walk, horizon, approach = (mpmath.mpf(value) for value in
                                            (mean0, std0, walk, horizon, approach))
    spread = mpmath.sqrt(std0 ** 2 + walk * horizon)
    reach = mean0 - approach * horizon
    if spread == 0:
        first = mpmath.mpf(0) if reach >= 0 else mpmath.mpf(1)
    else:
        first = mpmath.ncdf(-reach / spread)
    if walk == 0:
        return first
    before = std0 ** 2 / walk
    start = mean0 + approach * before
    if start <= 0:
        return mpmath.mpf(1)
    far = mean0 + approach * (horizon + 2 * before)
    reflected = mpmath.exp(2 * approach * start / walk) * mpmath.ncdf(-far / spread)
    return min(first + reflected, mpmath.mpf(1))


def relative_error(exact):
    """Return the error allowed relative to a bound: 1e-13, 1e-10 in tails beyond 1e-30.

    A tail ``Phi(-x)`` inherits the rounding of ``x`` amplified by ``d log Phi / dx``, about
    ``x``: ``x^2 2^-53`` relative. At the risks planned with (above 1e-9, x below 6) that is
    far below 1e-13; a bound of 1e-213 (x near 31) is off by 1.6e-13 of itself.
    """
    return 1e-13 if exact >= 1e-30 else 1e-10


def conditions(rng, count):
    """Return COUNT random conditions: mean0, std0, walk (K,) and a horizon, as the walls make."""
    mean0 = rng.uniform(-0.2, 3.0, count)
    std0 = rng.choice([0.0, 0.01, 0.05, 0.1, 0.2], count) * rng.uniform(0.5, 1.0, count)
    walk = 0.1 * rng.choice([0.0, 0.001, 0.01, 0.03], count) * rng.uniform(0.5, 1.0, count)
    return mean0, std0, walk, 2.0


def test_erfcx_is_exp_x_squared_times_erfc_to_a_few_ulps():
    """Across its switch to the continued fraction at 26 and up to 1e6, from mpmath."""
    for value in np.concatenate([np.linspace(0.0, 30.0, 3001), np.geomspace(30.0, 1e6, 200),
                                 np.nextafter(26.0, [0.0, 30.0])]):
        exact = mpmath.exp(mpmath.mpf(value) ** 2) * mpmath.erfc(mpmath.mpf(value))
        assert abs(erfcx(value) - exact) <= 1e-15 * exact, value
    assert math.isnan(erfcx(math.nan))


@pytest.mark.parametrize('seed', range(4))
def test_crossing_bounds_are_the_reflection_principle_bound(seed):
    """Every case: with and without a walk or a spread, approaching or not, x0 <= 0."""
    rng = np.random.default_rng(seed)
    mean0, std0, walk, horizon = conditions(rng, 400)
    approach = np.where(rng.uniform(size=400) < 0.2, 0.0, rng.uniform(0.0, 2.0, 400))
    bounds = crossing_bounds(mean0, std0, walk, horizon, approach)
    for index, bound in enumerate(bounds):
        exact = exact_bound(mean0[index], std0[index], walk[index], horizon, approach[index])
        assert 0.0 <= bound <= 1.0
        assert abs(bound - exact) <= relative_error(exact) * exact + 1e-300, (index, bound)


@pytest.mark.parametrize('seed', range(4))
def test_the_largest_accepted_speed_is_the_bound_s_root(seed):
    """``bound(approach) <= risk`` always, and ``approach`` is the root to within 1e-7 m/s."""
    rng = np.random.default_rng(seed)
    count = 200
    mean0, std0, walk, horizon = conditions(rng, count)
    risks = rng.choice([0.2, 0.05, 1e-3, 1e-6], count)
    # The planner's bracket: the first term's thresholds at half the risk and at the risk.
    quantile = np.vectorize(lambda p: float(-mpmath.sqrt(2) * mpmath.erfinv(1 - 2 * p)))
    still, approach = line_speeds(mean0, std0, walk, horizon, risks, quantile(0.5 * risks),
                                  quantile(risks))
    for index in range(count):
        arguments = mean0[index], std0[index], walk[index], horizon
        exact_still = exact_bound(*arguments, 0.0)
        assert abs(still[index] - exact_still) <= relative_error(exact_still) * exact_still \
            + 1e-300
        if not exact_still < risks[index]:
            assert approach[index] == -math.inf
            continue
        assert exact_bound(*arguments, approach[index]) <= risks[index] * (1.0 + 1e-12)
        # Bisection on the oracle: the largest speed whose bound is at most the risk.
        lower, upper = mpmath.mpf(0), mpmath.mpf(5)
        if exact_bound(*arguments, lower) > risks[index]:
            upper = lower
        while upper - lower > 1e-10:
            middle = (lower + upper) / 2
            lower, upper = ((middle, upper) if exact_bound(*arguments, middle) <= risks[index]
                            else (lower, middle))
        assert approach[index] == pytest.approx(float(lower), abs=1e-7)


def parallel_bound(model, point, radius, direction):
    """Return the crossing bound of the tangent to a disc parallel to DIRECTION, closed form.

    Moving along the tangent nothing approaches it, and the reflection principle's bound with no
    drift is twice the first term (the path straight, without a walk: the first term alone).
    """
    across = np.array([-direction[1], direction[0]])
    margin = abs((model.mean_position - point) @ across) - radius
    std0 = math.sqrt(max(across @ model.position_cov @ across, 0.0))
    walk = max(across @ model.walk_cov @ across, 0.0)
    if walk == 0.0:
        return float(norm.cdf(-margin / std0)) if std0 > 0.0 else float(margin < 0.0)
    if margin <= 0.0:
        return 1.0
    return min(2.0 * float(norm.cdf(-margin / math.sqrt(std0 ** 2
                                                      + walk * model.conditions.horizon))), 1.0)


def sampled_rejections(model, direction, speeds):
    """Return, per shape (wall, then disc) and speed on the ray, whether it is rejected.

    Pointwise from the definitions: a condition accepts ``v`` where ``n.v >= -approach``; a wall
    rejects where its support line does and one of its pieces (the rectangle: all four sides;
    an end in reach: its whole fan, unless its parallel tangent holds) does; a disc where its
    whole fan does, unless its parallel tangent holds; a close shape wherever moving away does
    not hold, ``n.v >= Phi^-1(eta) sqrt(n' S_a n)``.
    """
    conditions = model.conditions
    velocities = speeds[:, None] * direction
    accepts = velocities @ conditions.normals.T >= -conditions.approach
    walls, per_wall, fan = len(model.segments), 5 + 2 * 5, 5
    rejected = np.zeros((walls + len(model.centres), len(speeds)), dtype=bool)
    away = velocities @ model.away_normals.T < model.away_thresholds
    for wall in range(walls):
        first = wall * per_wall
        if model.close[wall]:
            rejected[wall] = away[:, wall]
            continue
        pieces = [~accepts[:, first + 1:first + 5].any(axis=1)]
        for end in range(2):
            start = first + 5 + end * fan
            held = (not model.end_in_reach[wall, end]) or parallel_bound(
                model, model.segments[wall, end], model.radius[wall],
                direction) <= conditions.risks[start]
            pieces.append(np.zeros(len(speeds), dtype=bool) if held
                          else ~accepts[:, start:start + fan].any(axis=1))
        rejected[wall] = ~accepts[:, first] & np.any(pieces, axis=0)
    for disc in range(len(model.centres)):
        first = walls * per_wall + disc * fan
        if model.close[walls + disc]:
            rejected[walls + disc] = away[:, walls + disc]
        elif parallel_bound(model, model.centres[disc], model.disc_radius[disc],
                            direction) > conditions.risks[first]:
            rejected[walls + disc] = ~accepts[:, first:first + fan].any(axis=1)
    return rejected


@pytest.mark.parametrize('seed', range(6))
def test_rejected_intervals_are_where_the_conditions_reject_on_dense_samples(seed):
    """Every wall's three intervals and every disc's one, against 401 speeds on 64 rays."""
    rng = np.random.default_rng(seed)
    segments = np.array([[[1.0, -5.0], [1.0, -0.45]], [[1.0, 0.45], [1.0, 5.0]],
                         [[-1.5, 1.0], [-1.0, 1.0]], [[-1.0, 1.0], [-1.0, 1.5]],
                         [[-1.0, 1.5], [-1.5, 1.5]], [[-1.5, 1.5], [-1.5, 1.0]],
                         [[-2.0, -2.0], [0.0, -1.2]]])
    world = StaticObstacles(segments, np.array([0.05, 0.05, 0.0, 0.0, 0.0, 0.0, 0.1]),
                            np.array([[0.0, 1.0], [2.0, -1.0]]), np.array([0.2, 0.3]))
    angles = 2.0 * np.pi * np.arange(64) / 64
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    speeds = np.linspace(0.0, 1.0, 401)
    shapes = 0
    for _ in range(10):
        std = rng.choice([0.0, 0.03, 0.1])
        covariance = np.diag([std ** 2, (0.7 * std) ** 2, 0.05 ** 2, 0.05 ** 2])
        ego = AgentBelief(rng.uniform([-2.0, -1.5], [2.5, 1.5]), [0.0, 0.0], covariance, 0.25)
        config = PlannerConfig(eta=float(rng.choice([0.8, 0.95])), max_speed=1.0,
                               actuation_cov=rng.choice([0.0, 0.05, 0.1]) ** 2 * np.eye(2))
        model = wall_model(world, ego, config)
        walls = len(model.segments)
        shapes += walls + len(model.centres)
        upper, lower = rejected_intervals(model, directions)
        for ray, direction in enumerate(directions):
            inside = (upper[:, ray, None] < speeds) & (speeds < lower[:, ray, None])
            found = np.concatenate([inside[:3 * walls].reshape(walls, 3, -1).any(axis=1),
                                    inside[3 * walls:]])
            # Away from the intervals' ends, where rounding could put a speed on either side.
            ends = np.concatenate([upper[:, ray], lower[:, ray]])
            clear = np.min(np.abs(speeds[:, None] - ends), axis=1, initial=np.inf) > 1e-9
            expected = sampled_rejections(model, direction, speeds)
            assert np.array_equal(found[:, clear], expected[:, clear]), (ray, model.close)
    assert shapes > 0


@pytest.mark.parametrize('seed', range(4))
def test_the_conditions_are_the_tangents_and_sides_of_the_grown_shapes(seed):
    """Each condition's line from closed-form geometry; distances from dense samples.

    Per near wall: the support line is at the grown radius ``R`` beyond the segment's farthest
    point along its normal, and its normal points from the segment's closest point (found by
    sampling 20,001 points of it) to ``mu``; the rectangle's sides are the wall's line moved by
    ``R`` either way and the lines across its ends; every fan tangent touches its end disc
    (its line at distance ``R`` from the centre) within ``arccos(R / d)`` of the direction to
    ``mu``. The risks split ``delta`` as stated: the rectangle and each end within reach an
    equal share of what the ends out of reach leave.
    """
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-3.0, 3.0, (12, 2))
    ends = starts + rng.uniform(-2.0, 2.0, (12, 2))
    world = StaticObstacles(np.stack([starts, ends], axis=1), rng.uniform(0.0, 0.1, 12),
                            rng.uniform(-3.0, 3.0, (4, 2)), rng.uniform(0.1, 0.4, 4))
    fractions = np.linspace(0.0, 1.0, 20001)[:, None]
    for _ in range(10):
        std = rng.choice([0.0, 0.05])
        ego = AgentBelief(rng.uniform(-2.0, 2.0, 2), [0.0, 0.0],
                          np.diag([std ** 2, std ** 2, 0.01, 0.01]), 0.25)
        config = PlannerConfig(eta=0.9, max_speed=1.0, actuation_cov=0.0025 * np.eye(2),
                               obstacle_horizon=1.0)
        model = wall_model(world, ego, config)
        mu, delta = model.mean_position, 0.1
        conditions = model.conditions
        # The lines n.x = c, with c from m0 = n.mu - c.
        normals = conditions.normals
        offsets = normals @ mu - conditions.mean0
        assert np.allclose(np.hypot(*normals.T), 1.0, atol=1e-12)
        grown = 0.25 + world.half_widths
        distances = [np.min(np.hypot(*(start + fractions * (end - start) - mu).T))
                     for start, end in zip(starts, ends, strict=True)]
        disc_distances = np.hypot(*(world.disc_centres - mu).T)
        assert model.clearance == pytest.approx(min(
            np.min(np.array(distances) - grown), np.min(disc_distances - 0.25
                                                        - world.disc_radii)), abs=1e-6)
        for row, (segment, radius) in enumerate(zip(model.segments, model.radius, strict=True)):
            first = 15 * row
            along = (segment[1] - segment[0]) / np.linalg.norm(segment[1] - segment[0])
            across = np.array([-along[1], along[0]])
            points = segment[0] + fractions * (segment[1] - segment[0])
            nearest = points[np.argmin(np.hypot(*(points - mu).T))]
            support = normals[first]
            if model.distance[row] > 1e-3:
                assert support == pytest.approx((mu - nearest) / np.linalg.norm(mu - nearest),
                                                abs=1e-3)
            assert offsets[first] == pytest.approx(max(segment @ support) + radius, abs=1e-12)
            for side, (normal, offset) in enumerate([
                    (across, across @ segment[0] + radius),
                    (-across, radius - across @ segment[0]),
                    (-along, -along @ segment[0]), (along, along @ segment[1])]):
                assert normals[first + 1 + side] == pytest.approx(normal, abs=1e-12)
                assert offsets[first + 1 + side] == pytest.approx(offset, abs=1e-12)
            for end in range(2):
                centre = segment[end]
                fan = slice(first + 5 + 5 * end, first + 10 + 5 * end)
                # Tangent: the centre is R inside each line.
                assert normals[fan] @ centre == pytest.approx(offsets[fan] - radius, abs=1e-12)
                towards = (mu - centre) / np.linalg.norm(mu - centre)
                opening = math.acos(min(radius / np.linalg.norm(mu - centre), 1.0))
                # The angle from the direction to mu, as atan2 (arccos loses half the digits).
                angles = np.arctan2(np.abs(normals[fan, 0] * towards[1]
                                           - normals[fan, 1] * towards[0]), normals[fan] @ towards)
                assert np.all(angles <= opening + 1e-9)
            share = conditions.risks[first + 1]
            ends_in = model.end_in_reach[row]
            assert conditions.risks[first] == pytest.approx(delta)
            assert share * (1 + ends_in.sum()) + model.end_bounds[row].sum() == pytest.approx(
                delta, rel=1e-12)
            for end in range(2):
                assert np.all(conditions.risks[first + 5 + 5 * end:first + 10 + 5 * end]
                              == (share if ends_in[end] else 0.0))
        assert len(model.segments) + len(model.centres) + len(model.far_bounds) == len(world)


@pytest.mark.parametrize('seed', range(3))
def test_the_probability_certified_is_the_best_decomposition_of_every_shape(seed):
    """``obstacle_probability`` from the conditions' bounds in mpmath, combined as stated.

    Per near wall the smaller failure of the support line and of the decomposition (the
    rectangle's best side plus each end's best tangent, the parallel one included when moving,
    or the end's a-priori bound when out of reach); per disc its best tangent; the largest of
    these and of the far shapes' bounds.
    """
    rng = np.random.default_rng(seed)
    segments = np.array([[[1.0, -5.0], [1.0, -0.45]], [[1.0, 0.45], [1.0, 5.0]],
                         [[-1.5, 1.0], [-1.0, 1.0]], [[-4.0, -6.0], [4.0, -6.0]]])
    world = StaticObstacles(segments, np.array([0.05, 0.05, 0.0, 0.1]),
                            np.array([[0.0, 1.0], [2.0, -1.0]]), np.array([0.2, 0.3]))
    for _ in range(3):
        ego = AgentBelief(rng.uniform([-0.5, -0.5], [0.3, 0.5]), [0.0, 0.0],
                          np.diag([0.004, 0.003, 0.01, 0.01]), 0.25)
        config = PlannerConfig(eta=0.9, max_speed=1.0, actuation_cov=0.0049 * np.eye(2))
        model = wall_model(world, ego, config)
        conditions = model.conditions
        for velocity in np.concatenate([[[0.0, 0.0], [0.6, 0.0]],
                                        rng.uniform(-0.8, 0.8, (2, 2))]):
            failures = [exact_bound(m0, s0, w, conditions.horizon, max(-(normal @ velocity), 0.0))
                        for normal, m0, s0, w in zip(conditions.normals, conditions.mean0,
                                                     conditions.std0, conditions.walk,
                                                     strict=True)]
            speed = np.hypot(*velocity)
            direction = velocity / speed if speed > 0.0 else None
            risks = list(model.far_bounds)
            for row in range(len(model.segments)):
                first = 15 * row
                decomposition = min(failures[first + 1:first + 5])
                for end in range(2):
                    if not model.end_in_reach[row, end]:
                        decomposition += model.end_bounds[row, end]
                        continue
                    best = min(failures[first + 5 + 5 * end:first + 10 + 5 * end])
                    if direction is not None:
                        best = min(best, parallel_bound(model, model.segments[row, end],
                                                        model.radius[row], direction))
                    decomposition += best
                risks.append(min(failures[first], decomposition))
            for disc in range(len(model.centres)):
                first = 15 * len(model.segments) + 5 * disc
                best = min(failures[first:first + 5])
                if direction is not None:
                    best = min(best, parallel_bound(model, model.centres[disc],
                                                    model.disc_radius[disc], direction))
                risks.append(best)
            expected = min(max(1.0 - float(max(risks, default=0.0)), 0.0), 1.0)
            assert obstacle_probability(model, velocity) == pytest.approx(expected, abs=1e-12)


def test_the_walls_cut_keeps_the_points_feasible_and_rejected_by_no_shape():
    rng = np.random.default_rng(11)
    rays, shapes, first_ray = 9, 7, 5
    gap_ray, lower, upper = [], [], []
    for ray in range(rays):
        # 0-3 disjoint closed intervals of [0, 1], two of them touching on ray 0.
        cuts = np.sort(rng.uniform(0.0, 1.0, 2 * rng.integers(0, 4)))
        if ray == 0:
            cuts = np.array([0.1, 0.4, 0.4, 0.7])
        for start, stop in cuts.reshape(-1, 2):
            gap_ray.append(first_ray + ray)
            lower.append(start)
            upper.append(stop)
    gap_ray, lower, upper = np.array(gap_ray), np.array(lower), np.array(upper)
    # Open intervals (upper, lower): some empty, some beyond [0, 1], some sharing an end.
    wall_upper = rng.uniform(-0.5, 1.2, (shapes, rays))
    wall_lower = wall_upper + rng.uniform(-0.2, 0.5, (shapes, rays))
    wall_upper[0, 0], wall_lower[0, 0] = 0.4, 0.55
    wall_upper[1, 0], wall_lower[1, 0] = 0.55, 0.6
    wall_lower[2:, 0] = wall_upper[2:, 0] - 0.1
    ray, kept_lower, kept_upper = cut_by_walls(gap_ray, lower, upper, first_ray,
                                               (wall_upper, wall_lower))
    assert np.all(kept_lower < kept_upper)
    order = np.lexsort((kept_lower, ray))
    assert np.array_equal(order, np.arange(ray.size))
    points = np.linspace(0.0, 1.0, 4001) + 1e-7 * math.pi
    for local in range(rays):
        own = gap_ray == first_ray + local
        feasible = np.any((lower[own, None] <= points) & (points <= upper[own, None]), axis=0)
        rejected = np.any((wall_upper[:, local, None] < points)
                          & (points < wall_lower[:, local, None]), axis=0)
        mine = ray == first_ray + local
        kept = np.any((kept_lower[mine, None] <= points) & (points <= kept_upper[mine, None]),
                      axis=0)
        assert np.array_equal(kept, feasible & ~rejected)
        # Every end is a feasible interval's end or a rejected interval's end.
        ends = np.concatenate([lower[own], upper[own], wall_upper[:, local],
                               wall_lower[:, local]])
        assert np.all(np.isin(np.concatenate([kept_lower[mine], kept_upper[mine]]), ends))
    # Ray 0's touching intervals stay apart; two rejected intervals sharing an end leave no
    # piece of no length between them.
    assert np.array_equal(kept_lower[ray == first_ray], [0.1, 0.6])
    assert np.array_equal(kept_upper[ray == first_ray], [0.4, 0.7])


def test_the_line_spreads_are_the_quadratic_forms_of_their_normals():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-math.pi, math.pi, 30)
    normals = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    away = normals[:7][::-1].copy()
    factor = rng.normal(size=(2, 2))
    position_cov = factor @ factor.T
    actuation_cov = np.diag([0.04, 0.01])
    risks = np.concatenate([[0.0, 2.0], rng.uniform(0.0, 0.1, 28)])
    std0, walk, solved, thresholds = wall_kernels.line_spreads(
        normals, away, position_cov, actuation_cov, 0.1, risks, 1.6448536269514722)
    for index, angle in enumerate(angles):
        # n' S n as the variance of n . x, with n = (cos a, sin a).
        c, s = math.cos(angle), math.sin(angle)
        across = (c * c * position_cov[0, 0] + s * s * position_cov[1, 1]
                  + 2.0 * c * s * position_cov[0, 1])
        assert std0[index] == pytest.approx(math.sqrt(across), rel=1e-12)
        assert walk[index] == pytest.approx(0.1 * (0.04 * c * c + 0.01 * s * s), rel=1e-12)
    assert solved[0] == 1e-300 and solved[1] == 1.0
    assert np.array_equal(solved[2:], risks[2:])
    for index, normal in enumerate(away):
        assert thresholds[index] == pytest.approx(
            1.6448536269514722 * math.sqrt(0.04 * normal[0] ** 2 + 0.01 * normal[1] ** 2),
            rel=1e-12)


@pytest.mark.parametrize('seed', range(3))
def test_the_model_s_spreads_bounds_and_close_shapes_follow_their_definitions(seed):
    """The model's two compiled calls (``wall_conditions``, ``wall_speeds``), by condition.

    Each condition's ``m0`` is ``n.mu - c`` with ``c`` the line's offset from closed-form
    geometry (the support line's farthest end plus ``R``, the rectangle's sides), in exact
    rational arithmetic; ``s0`` and the walk are the quadratic forms of ``S_p`` and ``T S_a``;
    the horizon is ``tau`` rounded up to whole periods; the bound standing still is the
    reflection principle's in mpmath; a shape is close where ``mu`` is within its grown radius
    or its support line's (a disc: its middle tangent's) bound standing still is at least
    ``delta``.
    """
    from fractions import Fraction

    rng = np.random.default_rng(10 + seed)
    starts = rng.uniform(-2.0, 2.0, (10, 2))
    ends = starts + rng.uniform(-2.0, 2.0, (10, 2))
    world = StaticObstacles(np.stack([starts, ends], axis=1), rng.uniform(0.0, 0.1, 10),
                            rng.uniform(-2.0, 2.0, (3, 2)), rng.uniform(0.1, 0.4, 3))
    close_seen = 0
    for _ in range(8):
        std = rng.choice([0.0, 0.05, 0.2])
        position_cov = np.array([[std ** 2, 0.3 * std ** 2], [0.3 * std ** 2, 0.5 * std ** 2]])
        cov = np.zeros((4, 4))
        cov[:2, :2], cov[2:, 2:] = position_cov, 0.01 * np.eye(2)
        ego = AgentBelief(rng.uniform(-1.5, 1.5, 2), [0.0, 0.0], cov, 0.25)
        actuation_cov = np.array([[0.0025, 0.001], [0.001, 0.004]])
        config = PlannerConfig(eta=0.95, max_speed=1.0, actuation_cov=actuation_cov,
                               obstacle_horizon=1.05, control_period=0.1)
        model = wall_model(world, ego, config)
        conditions = model.conditions
        delta = 1.0 - 0.95
        assert conditions.horizon == pytest.approx(1.1, abs=1e-12)
        mu = [Fraction(value) for value in model.mean_position]
        for index, normal in enumerate(conditions.normals):
            x, y = normal
            assert conditions.std0[index] == pytest.approx(math.sqrt(max(
                position_cov[0, 0] * x * x + 2 * position_cov[0, 1] * x * y
                + position_cov[1, 1] * y * y, 0.0)), rel=1e-12, abs=1e-300)
            assert conditions.walk[index] == pytest.approx(0.1 * (
                0.0025 * x * x + 0.002 * x * y + 0.004 * y * y), rel=1e-12)
            exact = exact_bound(conditions.mean0[index], conditions.std0[index],
                                conditions.walk[index], conditions.horizon, 0.0)
            assert conditions.still_risk[index] == pytest.approx(float(exact), rel=1e-10,
                                                                 abs=1e-300)
        for row, (segment, radius) in enumerate(zip(model.segments, model.radius, strict=True)):
            first = 15 * row
            along = (segment[1] - segment[0]) / np.linalg.norm(segment[1] - segment[0])
            across = np.array([-along[1], along[0]])
            support = conditions.normals[first]
            offsets = [max(segment @ support) + radius, across @ segment[0] + radius,
                       radius - across @ segment[0], -along @ segment[0], along @ segment[1]]
            for side, offset in enumerate(offsets):
                normal = conditions.normals[first + side]
                exact = (Fraction(normal[0]) * mu[0] + Fraction(normal[1]) * mu[1]
                         - Fraction(float(offset)))
                # The offsets here are rounded once more than the kernel's: a few ulps of R.
                assert conditions.mean0[first + side] == pytest.approx(float(exact), abs=1e-12)
            close = (model.distance[row] <= radius
                     or conditions.still_risk[first] >= delta)
            assert model.close[row] == close
            close_seen += close
        walls = len(model.segments)
        for row, radius in enumerate(model.disc_radius):
            middle = 15 * walls + 5 * row + 2
            close = (np.linalg.norm(model.mean_position - model.centres[row]) <= radius
                     or conditions.still_risk[middle] >= delta)
            assert model.close[walls + row] == close
            close_seen += close
    assert close_seen > 0


def test_cantelli_s_bound_of_arrays_is_k_squared_over_one_plus_k_squared():
    """Cantelli's bound of arrays (compiled) against the correctly rounded quotient.

    ``k^2 / (1 + k^2)`` in exact rational arithmetic, rounded once: the kernel's two roundings
    and the division stay within 2 ulps; 1 from ``k = 1e8`` on; negative margins are 0 when
    clipped and an error naming the margins otherwise; NaN is an error either way.
    """
    from fractions import Fraction

    from prvo_planner.core.probability import cantelli_of_margins, eta_from_k

    rng = np.random.default_rng(5)
    margins = np.concatenate([[0.0, 1e-160, 1e-8, 1.0, 9.99e7, 1e8, 3e160, math.inf],
                              10.0 ** rng.uniform(-5.0, 5.0, 200)])
    bounds = eta_from_k(margins)
    for k, bound in zip(margins, bounds, strict=True):
        if k >= 1e8:
            assert bound == 1.0
            continue
        exact = float(Fraction(k) ** 2 / (1 + Fraction(k) ** 2))
        assert abs(bound - exact) <= 2 * math.ulp(exact)
    grid = margins[:12].reshape(3, 4)
    assert np.array_equal(eta_from_k(grid), bounds[:12].reshape(3, 4))
    assert isinstance(eta_from_k(np.float64(2.0)), float)
    clipped = cantelli_of_margins(np.array([[-1.0, -0.0], [2.0, -math.inf]]))
    assert clipped.tolist() == [[0.0, 0.0], [0.8, 0.0]]
    with pytest.raises(ValueError, match=r'^k must be >= 0, got \[1.0, -0.5\]$'):
        eta_from_k(np.array([1.0, -0.5]))
    for margins in ([math.nan], [1.0, math.nan]):
        with pytest.raises(ValueError, match=r'^k must be >= 0'):
            cantelli_of_margins(np.array(margins))
        with pytest.raises(ValueError, match=r'^k must be >= 0'):
            eta_from_k(margins)


@pytest.mark.parametrize('seed', range(3))
def test_the_intrusion_is_the_deepest_overlap_of_the_sampled_path(seed):
    """How far a command moves into a shape within a period, from dense samples of the path.

    Per near shape ``min(d0, R) - d1``, ``d1`` the smallest distance of 401 points of the path
    ``mu + t v`` from 401 points of the segment (the disc's centre), 0 where the path crosses
    the segment; the largest over the shapes and 0. Sampling puts ``d1`` above the exact
    distance by at most the two samples' spacings, so the intrusion found lies between the
    sampled one and that much more.
    """
    rng = np.random.default_rng(20 + seed)
    starts = rng.uniform(-1.5, 1.5, (6, 2))
    ends = starts + rng.uniform(-1.5, 1.5, (6, 2))
    world = StaticObstacles(np.stack([starts, ends], axis=1), rng.uniform(0.0, 0.1, 6),
                            rng.uniform(-1.5, 1.5, (2, 2)), rng.uniform(0.1, 0.3, 2))
    fractions = np.linspace(0.0, 1.0, 401)[:, None]
    checked = 0
    for _ in range(4):
        ego = AgentBelief(rng.uniform(-1.0, 1.0, 2), [0.0, 0.0], 0.01 * np.eye(4), 0.25)
        model = wall_model(world, ego, PlannerConfig(max_speed=1.0))
        velocities = np.concatenate([rng.uniform(-2.0, 2.0, (12, 2)), [[0.0, 0.0]]])
        period = 0.5
        intrusion = walls_module.wall_intrusion(model, velocities, period)
        mu = model.mean_position
        for velocity, found in zip(velocities, intrusion, strict=True):
            path = mu + fractions * period * velocity
            expected = 0.0
            for segment, distance, radius in zip(model.segments, model.distance, model.radius,
                                                 strict=True):
                points = segment[0] + fractions * (segment[1] - segment[0])
                gaps = np.hypot(*(path[:, None, :] - points[None, :, :]).T)
                # Crossing: the sampled distance falls to the samples' spacing, or below.
                expected = max(expected, min(distance, radius) - gaps.min())
            for centre, radius in zip(model.centres, model.disc_radius, strict=True):
                expected = max(expected, min(np.linalg.norm(mu - centre), radius)
                               - np.hypot(*(path - centre).T).min())
            lengths = period * np.linalg.norm(velocity) + np.max(
                np.linalg.norm(model.segments[:, 1] - model.segments[:, 0], axis=1), initial=0.0)
            assert expected - 1e-12 <= found <= expected + lengths / 400.0
            checked += found > 0.0
        assert intrusion[-1] == pytest.approx(0.0, abs=1e-12) or np.min(
            model.distance - model.radius, initial=np.inf) < 0.0
    assert checked > 0


def test_the_time_to_contact_is_the_first_time_the_gap_closes():
    """The fallback's time to contact against the first sampled time each gap closes.

    Per near shape the gap ``max(d - R, 0)`` closes at the speed ``-n.v`` towards its line of
    moving away (``n`` the support line's normal, a disc's middle tangent's); the first of
    20,001 times in ``[0, tau]`` at which some gap is closed, ``tau`` where none closes.
    """
    rng = np.random.default_rng(30)
    starts = rng.uniform(-1.5, 1.5, (8, 2))
    world = StaticObstacles(np.stack([starts, starts + rng.uniform(-1.5, 1.5, (8, 2))], axis=1),
                            np.full(8, 0.05), rng.uniform(-1.5, 1.5, (2, 2)), np.full(2, 0.2))
    times = np.linspace(0.0, 2.0, 20001)
    contacts = 0
    for _ in range(4):
        ego = AgentBelief(rng.uniform(-1.0, 1.0, 2), [0.0, 0.0], 0.01 * np.eye(4), 0.25)
        model = wall_model(world, ego, PlannerConfig(max_speed=1.0, obstacle_horizon=2.0))
        velocities = np.concatenate([rng.uniform(-1.0, 1.0, (30, 2)), [[0.0, 0.0]]])
        found = walls_module.wall_time_to_contact(model, velocities)
        gaps = np.maximum(np.concatenate([
            model.distance - model.radius,
            np.linalg.norm(model.centres - model.mean_position, axis=1) - model.disc_radius]),
            0.0)
        for velocity, time in zip(velocities, found, strict=True):
            speeds = [-(normal @ velocity) for normal in model.away_normals]
            closed = np.any([(speed > 0.0) & (gap - speed * times <= 0.0)
                             for gap, speed in zip(gaps, speeds, strict=True)], axis=0)
            first = times[np.argmax(closed)] if closed.any() else 2.0
            assert first - 1e-4 - 1e-12 <= time <= first + 1e-12
            contacts += time < 2.0
        assert found[-1] == 2.0
    assert contacts > 10
