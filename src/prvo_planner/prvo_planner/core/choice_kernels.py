"""
The choice cost and the best speed on each feasible interval, compiled (:mod:`.choice`).

Five numba functions, each compiled for one signature when this module is first imported
(:mod:`.choice` imports it on its first cost; the planner's warm-up makes that call before the
node spins) and kept in numba's on-disk cache, as the ray search, the moments, the certificate
and the walls are (``./run.sh setup`` compiles every kernel module once after installing):

* :func:`choice_costs`, the cost of velocities, one row of cost terms per velocity;
* :func:`best_speeds`, the cheapest ``t`` on each interval of a ray ``t v_max e``: the
  projection of the preferred ``t``, a bound per plan, and a zoomed grid on the intervals that
  may hold their plan's optimum;
* :func:`cheapest_velocities`, per plan the cheapest velocity over its feasible intervals
  (:func:`best_speeds` on each, then the first of the smallest cost) and its number of rays
  with a feasible interval;
* :func:`search_margins`, the margins the certified plan searches each link with;
* :func:`fallback_measures`, the fallback's measures of candidate commands against the
  neighbours' means when no velocity is feasible.

Both use one formula, :func:`_cost`. A row of cost terms holds, in this order, ``v_pref``
(2), ``previous`` (2), ``inertia``, ``bias``, ``progress`` and ``norm`` (:class:`.CostTerms`).
numpy did the zoomed grid as a few dozen calls on (G, 17, 2) arrays, each of a few microseconds
whatever G.
"""

from numba import types
import numpy as np

from .ray_solver import READ_ONLY_FLAGS, READ_ONLY_INDICES, READ_ONLY_ROWS, READ_ONLY_VECTOR, jit

# The columns of a row of cost terms.
TERM_COLUMNS = 8
# The zoomed grid: 17 points over the interval, zoomed 5 times onto the best point's two cells
# (1/8 of the span each time): to 8^-5 (3e-5) of the interval.
_ZOOM_POINTS = 17
_ZOOM_LEVELS = 5

_COSTS_SIGNATURE = types.float64[::1](READ_ONLY_ROWS, READ_ONLY_ROWS)
_BEST_SIGNATURE = types.float64[::1](
    READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_ROWS,
    READ_ONLY_FLAGS, READ_ONLY_VECTOR, READ_ONLY_INDICES)
_CHEAPEST_SIGNATURE = types.Tuple((types.int64[::1], types.int64[::1], types.float64[::1]))(
    READ_ONLY_INDICES, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_ROWS, READ_ONLY_INDICES,
    READ_ONLY_INDICES, READ_ONLY_VECTOR, READ_ONLY_ROWS, READ_ONLY_FLAGS, READ_ONLY_VECTOR,
    types.float64)
_MARGINS_SIGNATURE = types.float64[:, ::1](
    READ_ONLY_ROWS, READ_ONLY_INDICES, READ_ONLY_INDICES, READ_ONLY_ROWS, READ_ONLY_FLAGS,
    types.int64, types.boolean)
_FALLBACK_SIGNATURE = types.Tuple((types.float64[::1], types.float64[::1], types.float64[::1],
                                   types.int64[::1]))(
    READ_ONLY_ROWS, READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_VECTOR, types.float64,
    types.float64)


@jit(inline='always')
def _cost(x, y, terms):
    """
    Return the choice cost of the velocity ``(x, y)`` under one row of TERMS (8,).

    ``(1 - progress) |v - v_pref| + inertia |v - previous| + bias max(0, left(v)) + progress
    | |v_pref| - along(v) |`` (docs/method.md, section 7), with ``along`` and ``left`` the
    components of ``v`` along and to the left of ``v_pref``'s direction. Every term is convex in
    ``v``; a term of weight 0 adds exactly 0.
    """
    pref_x, pref_y, norm = terms[0], terms[1], terms[7]
    inertia, bias, progress = terms[4], terms[5], terms[6]
    cost = np.sqrt((x - pref_x) * (x - pref_x) + (y - pref_y) * (y - pref_y))
    cost *= 1.0 - progress
    cost += inertia * np.sqrt((x - terms[2]) * (x - terms[2]) + (y - terms[3]) * (y - terms[3]))
    cost += bias * max((pref_x * y - pref_y * x) / norm, 0.0)
    cost += progress * abs(norm - (pref_x * x + pref_y * y) / norm)
    return cost


@jit(_COSTS_SIGNATURE)
def choice_costs(velocities, terms):
    """
    Cost of each of VELOCITIES (P, 2) under TERMS (R, 8), shape (P,): smaller is better.

    The velocities are R equal runs, one per row of terms (R = 1: all under one plan's terms).
    """
    count = velocities.shape[0]
    run = count // terms.shape[0]
    costs = np.empty(count)
    for point in range(count):
        costs[point] = _cost(velocities[point, 0], velocities[point, 1], terms[point // run])
    return costs


@jit(inline='always')
def _cheaper(cost, best_cost):
    """Whether COST replaces BEST_COST in a first-of-the-smallest search (NaN first, as argmin)."""
    return cost < best_cost or (np.isnan(cost) and not np.isnan(best_cost))


@jit()
def _zoomed_speed(direction_x, direction_y, lower, upper, projected, terms):
    """
    Minimise the cost over ``t`` in ``[lower, upper]`` on the ray ``t (direction_x, direction_y)``.

    The cost is convex along the ray, so its minimum lies within one cell of the best point of a
    grid; the grid is zoomed onto those two cells. The final candidates are the last cell's
    middle, the projected ``t`` and the interval's ends (a flat or kinked minimum); the first
    cheapest is returned.
    """
    low, high = lower, upper
    for _ in range(_ZOOM_LEVELS):
        span = high - low
        best, best_cost = 0, np.inf
        for point in range(_ZOOM_POINTS):
            t = low + span * (point / (_ZOOM_POINTS - 1))
            cost = _cost(t * direction_x, t * direction_y, terms)
            if _cheaper(cost, best_cost):
                best, best_cost = point, cost
        new_low = low + span * (max(best - 1, 0) / (_ZOOM_POINTS - 1))
        high = low + span * (min(best + 1, _ZOOM_POINTS - 1) / (_ZOOM_POINTS - 1))
        low = new_low
    chosen = 0.5 * (low + high)
    chosen_cost = _cost(chosen * direction_x, chosen * direction_y, terms)
    for option in (projected, lower, upper):
        cost = _cost(option * direction_x, option * direction_y, terms)
        if _cheaper(cost, chosen_cost):
            chosen, chosen_cost = option, cost
    return chosen


@jit(_BEST_SIGNATURE)
def best_speeds(directions, lower, upper, preferred, terms, extra, max_speed, robot):
    """
    Best ``t`` in ``[lower, upper]`` on each ray ``t v_max e``, shape (G,).

    Under the plain cost (``extra`` false) it is the preferred ``t`` projected onto the
    interval. Otherwise the plain term alone (its share ``1 - progress`` of the cost), smallest
    at the projected ``t``, bounds an interval's cost from below (the other terms are >= 0),
    and the full cost at a projected ``t`` bounds its plan's optimum from above: only intervals
    whose lower bound reaches their plan's smallest upper bound are searched
    (:func:`_zoomed_speed`); the others keep the projected ``t``, whose cost cannot be the
    smallest.

    Parameters
    ----------
    directions : numpy.ndarray
        Ray directions ``e``, shape (G, 2).
    lower, upper, preferred : numpy.ndarray
        Interval ends and preferred ``t``, shape (G,).
    terms : numpy.ndarray
        Cost terms per interval, shape (G, 8).
    extra : numpy.ndarray
        Whether any term besides ``|v - v_pref|`` is on, per interval, shape (G,).
    max_speed : numpy.ndarray
        ``v_max`` per interval, shape (G,).
    robot : numpy.ndarray
        Plan of each interval, non-decreasing, shape (G,).

    """
    count = lower.shape[0]
    best = np.empty(count)
    for row in range(count):
        best[row] = min(max(preferred[row], lower[row]), upper[row])
    if not extra.any():
        return best
    full = np.empty(count)
    plain = np.empty(count)
    for row in range(count):
        x = max_speed[row] * best[row] * directions[row, 0]
        y = max_speed[row] * best[row] * directions[row, 1]
        full[row] = _cost(x, y, terms[row])
        plain[row] = np.sqrt((x - terms[row, 0]) * (x - terms[row, 0])
                             + (y - terms[row, 1]) * (y - terms[row, 1])) * (1.0 - terms[row, 6])
    start = 0
    while start < count:
        stop = start + 1
        while stop < count and robot[stop] == robot[start]:
            stop += 1
        bound = full[start:stop].min()
        for row in range(start, stop):
            if extra[row] and plain[row] <= bound:
                best[row] = _zoomed_speed(
                    max_speed[row] * directions[row, 0], max_speed[row] * directions[row, 1],
                    lower[row], upper[row], best[row], terms[row])
        start = stop
    return best


@jit(_CHEAPEST_SIGNATURE)
def cheapest_velocities(gap_ray, lower, upper, directions, ray_robot, ray_local, preferred,
                        terms, extra, max_speed, interior):
    """
    Per plan, its cheapest velocity over its feasible intervals.

    Each interval, shrunk by ``min(interior, half its length)`` at each end, gets its best
    ``t`` (:func:`best_speeds`); a plan's choice is its first interval of the smallest cost
    (NaN costs last).

    Parameters
    ----------
    gap_ray, lower, upper : numpy.ndarray
        Feasible intervals (ray, lower, upper), shape (G,), grouped by plan.
    directions : numpy.ndarray
        Every ray's direction, shape (R, 2).
    ray_robot, ray_local : numpy.ndarray
        Each ray's plan and index among its plan's directions, shape (R,).
    preferred : numpy.ndarray
        Preferred ``t`` per ray, shape (R,).
    terms, extra, max_speed : numpy.ndarray
        Per plan its cost terms (P, 8), whether any term besides ``|v - v_pref|`` is on (P,)
        and ``v_max`` (P,).
    interior : float
        How far inside an interval a chosen ``t`` stays.

    Returns
    -------
    feasible_rays : numpy.ndarray
        Per plan, how many of its rays have a feasible interval, shape (P,).
    direction, t : numpy.ndarray
        Per plan the chosen direction's index among its own and ``t``, shape (P,) each
        (-1 and NaN for a plan without an interval).

    """
    plans = terms.shape[0]
    count = gap_ray.shape[0]
    feasible_rays = np.zeros(plans, dtype=np.int64)
    seen = np.zeros(ray_robot.shape[0], dtype=np.bool_)
    gap_directions = np.empty((count, 2))
    inner_lower = np.empty(count)
    inner_upper = np.empty(count)
    gap_preferred = np.empty(count)
    gap_terms = np.empty((count, TERM_COLUMNS))
    gap_extra = np.empty(count, dtype=np.bool_)
    gap_speed = np.empty(count)
    gap_robot = np.empty(count, dtype=np.int64)
    for gap in range(count):
        ray = gap_ray[gap]
        robot = ray_robot[ray]
        if not seen[ray]:
            seen[ray] = True
            feasible_rays[robot] += 1
        inset = min(interior, 0.5 * (upper[gap] - lower[gap]))
        inner_lower[gap] = lower[gap] + inset
        inner_upper[gap] = upper[gap] - inset
        gap_directions[gap, 0] = directions[ray, 0]
        gap_directions[gap, 1] = directions[ray, 1]
        gap_preferred[gap] = preferred[ray]
        gap_terms[gap] = terms[robot]
        gap_extra[gap] = extra[robot]
        gap_speed[gap] = max_speed[robot]
        gap_robot[gap] = robot
    best_t = best_speeds(gap_directions, inner_lower, inner_upper, gap_preferred, gap_terms,
                         gap_extra, gap_speed, gap_robot)
    direction = np.full(plans, -1, dtype=np.int64)
    chosen_t = np.full(plans, np.nan)
    chosen_cost = np.full(plans, np.nan)
    for gap in range(count):
        robot = gap_robot[gap]
        speed = gap_speed[gap] * best_t[gap]
        cost = _cost(speed * gap_directions[gap, 0], speed * gap_directions[gap, 1],
                     terms[robot])
        best_cost = chosen_cost[robot]
        if direction[robot] < 0 or cost < best_cost or (np.isnan(best_cost)
                                                        and not np.isnan(cost)):
            direction[robot] = ray_local[gap_ray[gap]]
            chosen_t[robot] = best_t[gap]
            chosen_cost[robot] = cost
    return feasible_rays, direction, chosen_t


@jit(_MARGINS_SIGNATURE)
def search_margins(cantelli, link_pair, pair_robot, robot_margins, gated, columns, horizon):
    """
    Return the margins (L, C) a certified plan searches its links with, from CANTELLI's (L, C).

    The first COLUMNS (``f``, and ``g`` with a receding condition) take their robot's search
    margin, ``robot_margins[:, 0]``; with a HORIZON, the last three (``h1, h2, h3``) of the
    neighbours whose gate counts (GATED, per pair) take its horizon search margin,
    ``robot_margins[:, 1]``. LINK_PAIR is each link's neighbour, PAIR_ROBOT each neighbour's
    robot.
    """
    margins = cantelli.copy()
    last = cantelli.shape[1]
    for link in range(cantelli.shape[0]):
        pair = link_pair[link]
        robot = pair_robot[pair]
        for column in range(columns):
            margins[link, column] = robot_margins[robot, 0]
        if horizon and gated[pair]:
            for column in range(last - 3, last):
                margins[link, column] = robot_margins[robot, 1]
    return margins


@jit(_FALLBACK_SIGNATURE)
def fallback_measures(velocities, origin, lead, radius, horizon, period):
    """
    Return the fallback's measures of VELOCITIES (K, 2) against N neighbours (:mod:`.choice`).

    ORIGIN (N, 4) is ``(r, u)`` at zero command, LEAD (N,) the command's factor in ``u``,
    RADIUS (N,) the ranking radius; :func:`.choice.fallback_measures` documents the four
    measures (intrusion, closing, time to collision capped at HORIZON, left passes) and PERIOD.
    Each (neighbour, command) pair is evaluated by the formulas numpy applied elementwise, in
    the same order of operations; the maxima, minima and counts over neighbours do not depend
    on their order.
    """
    count = velocities.shape[0]
    neighbours = origin.shape[0]
    fastest = 0.0
    for candidate in range(count):
        speed = np.sqrt(velocities[candidate, 0] * velocities[candidate, 0]
                        + velocities[candidate, 1] * velocities[candidate, 1])
        fastest = max(fastest, speed)
    distance_sq = np.empty(neighbours)
    distance = np.empty(neighbours)
    contact = np.empty(neighbours)
    divisor = np.empty(neighbours)
    clearance = np.empty(neighbours)
    near = np.empty(neighbours, dtype=np.bool_)
    touching = np.empty(neighbours, dtype=np.bool_)
    for neighbour in range(neighbours):
        distance_sq[neighbour] = (origin[neighbour, 0] * origin[neighbour, 0]
                                  + origin[neighbour, 1] * origin[neighbour, 1])
        distance[neighbour] = np.sqrt(distance_sq[neighbour])
        contact[neighbour] = min(distance[neighbour], radius[neighbour])
        divisor[neighbour] = max(distance[neighbour], 1e-12)
        clearance[neighbour] = distance_sq[neighbour] - radius[neighbour] * radius[neighbour]
        reach = period * (lead[neighbour] * fastest
                          + np.hypot(origin[neighbour, 2], origin[neighbour, 3]))
        near[neighbour] = distance[neighbour] < radius[neighbour] + reach
        touching[neighbour] = distance[neighbour] < radius[neighbour]
    intrusion = np.zeros(count)
    closing = np.zeros(count)
    time_to_collision = np.empty(count)
    left_passes = np.zeros(count, dtype=np.int64)
    for candidate in range(count):
        velocity_x, velocity_y = velocities[candidate, 0], velocities[candidate, 1]
        deepest, fastest_closing, first_hit, passes = 0.0, 0.0, np.inf, 0
        for neighbour in range(neighbours):
            position_x, position_y = origin[neighbour, 0], origin[neighbour, 1]
            relative_x = lead[neighbour] * velocity_x + origin[neighbour, 2]
            relative_y = lead[neighbour] * velocity_y + origin[neighbour, 3]
            along = position_x * relative_x + position_y * relative_y
            speed_sq = relative_x * relative_x + relative_y * relative_y
            # The closest the centres come within the period, at t = -r.u / |u|^2 clipped.
            closest_time = -along / speed_sq if speed_sq > 0.0 else 0.0
            closest_time = min(max(closest_time, 0.0), period)
            gap_x = position_x + closest_time * relative_x
            gap_y = position_y + closest_time * relative_y
            closest = np.sqrt(gap_x * gap_x + gap_y * gap_y)
            deepest = max(deepest, contact[neighbour] - closest)
            if near[neighbour]:
                fastest_closing = max(fastest_closing, -along / divisor[neighbour])
            # |r + t u|^2 = R^2 ahead: approaching, within R of the line, not touching; the
            # smaller root as c / (-b + sqrt(disc)).
            discriminant = along * along - speed_sq * clearance[neighbour]
            if along < 0.0 and discriminant >= 0.0 and not touching[neighbour]:
                first = clearance[neighbour] / (-along + np.sqrt(discriminant))
                first_hit = min(first_hit, first)
            cross = position_x * relative_y - position_y * relative_x
            if along < 0.0 and cross < 0.0:
                passes += 1
        intrusion[candidate] = deepest
        closing[candidate] = fastest_closing
        time_to_collision[candidate] = min(first_hit, horizon)
        left_passes[candidate] = passes
    return intrusion, closing, time_to_collision, left_passes
