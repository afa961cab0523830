"""
The choice cost and the best speed on each feasible interval, compiled (:mod:`.choice`).

Two numba functions, each compiled for one signature when this module is first imported
(:mod:`.choice` imports it on its first cost; the planner's warm-up makes that call before the
node spins) and kept in numba's on-disk cache, as the ray search, the moments, the certificate
and the walls are (``./run.sh setup`` compiles every kernel module once after installing):

* :func:`choice_costs`, the cost of velocities, one row of cost terms per velocity;
* :func:`best_speeds`, the cheapest ``t`` on each interval of a ray ``t v_max e``: the
  projection of the preferred ``t``, a bound per plan, and a zoomed grid on the intervals that
  may hold their plan's optimum.

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
