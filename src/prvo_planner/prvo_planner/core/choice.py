"""
The choice among feasible velocities, and the ranking of candidates when none is feasible.

The cost of a velocity is ``(1 - progress) |v - v_pref| + progress | |v_pref| - along(v) | +
inertia |v - previous| + passing_bias max(0, left(v))``; the terms only rank velocities that the
constraints already admit. Without a
feasible velocity, candidates are ranked by how far they move into contact within one control
period, how fast they close on neighbours they could touch within it, how soon they would
collide, and the cost, mirror ties going to the side that passes on the right
(``fallback_measures``, ``fallback_index``).
"""

from dataclasses import dataclass
import math

import numpy as np

from .probability import confidence_ellipse_scale

# Speeds, as fractions of v_max, tried on every direction when no direction is feasible (and by
# the Monte Carlo baseline), besides the preferred speed on the direction.
_SPEED_GRID = np.linspace(0.0, 1.0, 9)
# The best speed on a ray under the inertia / passing-bias cost: a grid of 17 points over the
# interval, zoomed 5 times onto the best point's two cells (1/8 of the span each time): to
# 8^-5 (3e-5) of the interval.
_ZOOM_GRID = np.linspace(0.0, 1.0, 17)
_ZOOM_LEVELS = 5
_TERM_NAMES = ('v_pref', 'previous', 'inertia', 'bias', 'progress', 'norm', 'extra')
# Chosen speeds stay this far (in t) inside a feasible interval so that rounding in the roots
# cannot put them on the rejected side.
INTERIOR = 1e-9


def _distances(points, point):
    """Euclidean distances of POINTS (..., 2) from POINT (2,), shape (...)."""
    offset = points - point
    # sqrt of a sum, not np.linalg.norm: a fraction of the cost on the small arrays of a plan.
    return np.sqrt(offset[..., 0] * offset[..., 0] + offset[..., 1] * offset[..., 1])


@dataclass(frozen=True)
class CostTerms:
    """
    The terms of the choice cost of one or several plans, broadcastable against velocities.

    Attributes
    ----------
    v_pref : numpy.ndarray
        Preferred velocity, shape (..., 2).
    previous : numpy.ndarray
        Previous command, shape (..., 2) (any value where ``inertia`` is 0).
    inertia : numpy.ndarray or float
        Weight of ``|v - previous|``: 0 without a previous command.
    bias : numpy.ndarray or float
        Weight of ``max(0, left(v))``: 0 when ``v_pref`` has no direction.
    progress : numpy.ndarray or float
        Share ``p`` of the goal term given to ``| |v_pref| - along(v) |``: 0 when ``v_pref``
        has no direction.
    norm : numpy.ndarray or float
        ``|v_pref|`` (1 where ``bias`` and ``progress`` are 0).
    extra : numpy.ndarray or bool
        Whether any term besides ``|v - v_pref|`` is on.

    """

    v_pref: np.ndarray
    previous: np.ndarray
    inertia: np.ndarray
    bias: np.ndarray
    progress: np.ndarray
    norm: np.ndarray
    extra: np.ndarray

    @classmethod
    def of_plan(cls, v_pref, previous, config):
        """Return the terms of one plan."""
        inertia = config.inertia if previous is not None else 0.0
        norm = math.hypot(v_pref[0], v_pref[1])
        bias = config.passing_bias if norm > 1e-9 else 0.0
        progress = config.progress_weight if norm > 1e-9 else 0.0
        return cls(v_pref=v_pref, previous=v_pref if previous is None else previous,
                   inertia=inertia, bias=bias, progress=progress,
                   norm=norm if bias > 0.0 or progress > 0.0 else 1.0,
                   extra=inertia > 0.0 or bias > 0.0 or progress > 0.0)

    @classmethod
    def stacked(cls, terms, index):
        """Return per-row terms: row ``r`` is ``terms[index[r]]`` (a sequence of CostTerms)."""
        return cls(*(np.array([getattr(term, name) for term in terms])[index]
                     for name in _TERM_NAMES))

    def take(self, index):
        """Return the terms of rows ``index`` (of per-row terms), one row per index."""
        return CostTerms(*(np.asarray(getattr(self, name))[index] for name in _TERM_NAMES))

    def rows(self):
        """Return per-row terms with a trailing axis, to broadcast against a grid per row."""
        return CostTerms(*(np.asarray(getattr(self, name))[:, None] for name in _TERM_NAMES))

    def costs(self, velocities):
        """
        Cost of commanded velocities, shape (..., 2) -> (...): smaller is better.

        ``(1 - progress) |v - v_pref| + progress | |v_pref| - along(v) |`` (docs/method.md,
        section 7), plus ``inertia |v - previous|`` and ``bias max(0, left(v))``, with
        ``along`` and ``left`` the components of ``v`` along and to the left of ``v_pref``'s
        direction. The progress share charges only the speed lost towards the goal, not the
        speed sideways: it prefers passing a crowd at speed to slowing down behind it. Every
        term is convex in ``v`` and only ranks velocities; which ones are acceptable is decided
        by the constraints alone. A term of weight 0 adds exactly 0.
        """
        costs = _distances(velocities, self.v_pref)
        costs *= 1.0 - self.progress
        costs += self.inertia * _distances(velocities, self.previous)
        left = (self.v_pref[..., 0] * velocities[..., 1]
                - self.v_pref[..., 1] * velocities[..., 0]) / self.norm
        costs += self.bias * np.maximum(left, 0.0)
        along = (self.v_pref[..., 0] * velocities[..., 0]
                 + self.v_pref[..., 1] * velocities[..., 1]) / self.norm
        costs += self.progress * np.abs(self.norm - along)
        return costs


def choice_costs(velocities, v_pref, previous, config):
    """Cost of commanded velocities of one plan, shape (..., 2) -> (...) (``CostTerms``)."""
    return CostTerms.of_plan(v_pref, previous, config).costs(velocities)


def best_speeds(directions, lower, upper, preferred, terms, max_speed, robot):
    """
    Best ``t`` in ``[lower, upper]`` on each ray ``t v_max e``, shape (G,).

    Under the plain cost it is the preferred ``t`` projected onto the interval. The extra terms
    of :class:`CostTerms` keep the cost convex along the ray, so its minimum lies within a
    cell of the best point of a grid; zooming a grid onto those two cells a few times finds it
    (the interval ends and the plain optimum are candidates too: a flat or kinked minimum).
    Only intervals that can hold their plan's optimum are searched; the others keep the
    projected ``t``, whose cost cannot be the smallest.

    Parameters
    ----------
    directions : numpy.ndarray
        Ray directions, shape (G, 2).
    lower, upper, preferred : numpy.ndarray
        Interval ends and preferred ``t``, shape (G,).
    terms : CostTerms
        Per interval, shape (G, ...).
    max_speed : numpy.ndarray
        ``v_max`` per interval, shape (G,).
    robot : numpy.ndarray
        Plan of each interval, non-decreasing, shape (G,).

    """
    projected = np.clip(preferred, lower, upper)
    extra = np.broadcast_to(terms.extra, projected.shape)
    if not extra.any():
        return projected
    # The plain term alone (its share of the cost), smallest at the projected t, bounds an
    # interval's cost from below (the other terms are >= 0); the full cost at a projected t
    # bounds the plan's optimum from above.
    at_projected = max_speed[:, None] * projected[:, None] * directions
    plain = _distances(at_projected, terms.v_pref) * (1.0 - terms.progress)
    full = terms.costs(at_projected)
    starts = np.flatnonzero(np.diff(robot, prepend=-1))
    bound = np.repeat(np.minimum.reduceat(full, starts), np.diff(np.append(starts, robot.size)))
    searched = (extra & (plain <= bound)).nonzero()[0]
    best = projected.copy()
    best[searched] = _zoomed_speeds(directions[searched], lower[searched], upper[searched],
                                    projected[searched], terms.take(searched),
                                    max_speed[searched])
    return best


def _zoomed_speeds(directions, lower, upper, projected, terms, max_speed):
    """Minimise the cost on each ray's interval by a zoomed grid, shape (G,)."""
    velocity_directions = max_speed[:, None, None] * directions[:, None, :]
    row_terms = terms.rows()
    low, high = lower, upper
    for _ in range(_ZOOM_LEVELS):
        grid = low[:, None] + (high - low)[:, None] * _ZOOM_GRID
        best = np.argmin(row_terms.costs(grid[..., None] * velocity_directions), axis=1)
        rows = np.arange(grid.shape[0])
        # The minimum of a convex function lies within one cell of the best grid point.
        low = grid[rows, np.maximum(best - 1, 0)]
        high = grid[rows, np.minimum(best + 1, _ZOOM_GRID.size - 1)]
    options = np.stack([0.5 * (low + high), projected, lower, upper], axis=1)
    option_costs = row_terms.costs(options[..., None] * velocity_directions)
    return options[np.arange(options.shape[0]), np.argmin(option_costs, axis=1)]


def speed_grid(directions, preferred, v_pref, previous, config):
    """
    Candidate speeds for sampling-based choices and their choice costs.

    Returns
    -------
    speeds : numpy.ndarray
        ``t`` per direction, shape (M, T): the preferred one (clipped), then a fixed grid.
    costs : numpy.ndarray
        :func:`choice_costs` of ``t v_max e``, shape (M, T).

    """
    speeds = np.concatenate([np.clip(preferred, 0.0, 1.0)[:, None],
                             np.broadcast_to(_SPEED_GRID, (directions.shape[0],
                                                           _SPEED_GRID.size))], axis=1)
    costs = choice_costs(config.max_speed * speeds[..., None] * directions[:, None, :], v_pref,
                          previous, config)
    return speeds, costs


def ranking_radius(encounter, model):
    """
    Radius of each neighbour the fallback ranks with, shape (N,).

    The means' combined radius grown, as the ``inflate`` model does, by the ``k`` confidence
    ellipse of the relative position, so that uncertain neighbours are kept further away; the
    ``rvo`` model plans on the means alone and keeps the plain radius.
    """
    if model == 'rvo':
        return encounter.combined_radius
    spread = np.linalg.eigvalsh(encounter.cov[:, :2, :2])[:, -1]
    return encounter.combined_radius + confidence_ellipse_scale(encounter.margin) * np.sqrt(
        np.maximum(spread, 0.0))


def fallback_measures(velocities, origin, lead, radius, horizon, period):
    """
    Return the fallback's measures of candidate commands against the neighbours' means.

    With ``r`` a neighbour's mean relative position and ``u = lead v + origin_u`` the relative
    velocity at command ``v`` when both keep to their shares of the avoidance (docs/method.md,
    sections 2 and 11), the gap to a neighbour can shrink by at most ``reach = period (lead
    v_top + |origin_u|)`` over one control period, ``v_top`` the fastest candidate; a neighbour
    is *near* when ``|r| < R + reach``: some candidate could touch it before the next plan. The
    measures need no variance and stay defined in overlap.

    Parameters
    ----------
    velocities : numpy.ndarray
        Candidate commands, shape (K, 2).
    origin : numpy.ndarray
        ``(r, u)`` at zero command per neighbour, shape (N, 4) (``Encounter.origin``).
    lead : numpy.ndarray
        Factor of the command in ``u`` per neighbour, shape (N,) (``Encounter.lead``).
    radius : numpy.ndarray
        Radius ``R`` per neighbour, shape (N,).
    horizon : float
        Times to collision are capped here (``inf``: uncapped).
    period : float
        How long the command stays in force, seconds.

    Returns
    -------
    intrusion : numpy.ndarray
        Shape (K,): how far, at most over the neighbours, the command moves into contact within
        one period, ``min(|r|, R) - min over t in [0, period] of |r + t u|`` (0 if nowhere):
        the overlap it creates, or adds to an existing one.
    closing : numpy.ndarray
        Shape (K,): the fastest a near neighbour closes in, ``max(0, -r . u / |r|)``
        (0 without near neighbours, or when each one recedes).
    time_to_collision : numpy.ndarray
        Shape (K,): the first ``t >= 0`` at which ``|r + t u| = R`` for a neighbour that is
        not touching, smallest over those neighbours, capped at ``horizon``.
    left_passes : numpy.ndarray
        Shape (K,): how many approaching neighbours (``r . u < 0``) the command passes on its
        left, ``r x u < 0``: a side both robots of a pair see the same way.

    """
    position = origin[:, None, :2]
    relative = lead[:, None, None] * velocities[None, :, :] + origin[:, None, 2:]
    along = np.sum(position * relative, axis=-1)
    speed_sq = np.sum(relative * relative, axis=-1)
    distance_sq = np.sum(origin[:, :2] * origin[:, :2], axis=1)
    distance = np.sqrt(distance_sq)
    # The closest the centres come within the period, at t = -r.u / |u|^2 clipped to it.
    with np.errstate(divide='ignore', invalid='ignore'):
        closest_time = np.clip(np.where(speed_sq > 0.0, -along / speed_sq, 0.0), 0.0, period)
    closest = np.sqrt(np.sum((position + closest_time[..., None] * relative) ** 2, axis=-1))
    intrusion = np.max(np.maximum(np.minimum(distance, radius)[:, None] - closest, 0.0),
                       axis=0, initial=0.0)
    fastest = np.max(np.sqrt(np.sum(velocities * velocities, axis=1)), initial=0.0)
    reach = period * (lead * fastest + np.hypot(origin[:, 2], origin[:, 3]))
    near = distance < radius + reach
    closing = np.max(np.maximum(-along / np.maximum(distance, 1e-12)[:, None], 0.0), axis=0,
                     where=near[:, None], initial=0.0)
    # |r + t u|^2 = R^2: a t^2 + 2 b t + c = 0 with c > 0 (not touching); the first root is
    # ahead only when approaching (b < 0) and the line passes within R (b^2 >= a c).
    touching = distance < radius
    clearance = (distance_sq - radius * radius)[:, None]
    discriminant = along * along - speed_sq * clearance
    hits = (along < 0.0) & (discriminant >= 0.0) & ~touching[:, None]
    with np.errstate(divide='ignore', invalid='ignore'):
        # The smaller root as c / (-b + sqrt(disc)): no cancellation, and finite as a -> 0.
        first = clearance / (-along + np.sqrt(np.maximum(discriminant, 0.0)))
    time_to_collision = np.min(np.where(hits, first, np.inf), axis=0, initial=np.inf)
    cross = position[..., 0] * relative[..., 1] - position[..., 1] * relative[..., 0]
    left_passes = np.sum((along < 0.0) & (cross < 0.0), axis=0)
    return intrusion, closing, np.minimum(time_to_collision, horizon), left_passes


def fallback_index(intrusion, closing, time_to_collision, left_passes, costs, walls=None):
    """
    Index of the fallback's choice among candidates, all shape (K,).

    Lexicographic: the least intrusion into static obstacles within the period (with WALLS,
    a pair ``(intrusion, time_to_contact)`` of shape (K,) each; 0 for standing still, so the
    choice never drives deeper into a wall), then the least intrusion into contact with
    neighbours (0 whenever some candidate touches nobody new and presses into no overlap),
    then (with WALLS) the longest time to reach a wall's support line, then the least closing
    on near neighbours, then the longest time to collision, then the smallest cost. Among
    candidates of equal cost (mirror images in a symmetric encounter), the fewest neighbours
    passed on the left: both robots of a pair then pass on the right.
    """
    if walls is None:
        ranked = intrusion <= np.min(intrusion) + 1e-9
    else:
        wall_intrusion, time_to_contact = walls
        ranked = wall_intrusion <= np.min(wall_intrusion) + 1e-9
        ranked &= intrusion <= np.min(intrusion[ranked]) + 1e-9
        longest = np.max(time_to_contact[ranked])
        ranked &= time_to_contact >= longest - 1e-9 * max(1.0, longest)
    ranked &= closing <= np.min(closing[ranked]) + 1e-9
    longest = np.max(time_to_collision[ranked])
    if np.isfinite(longest):
        ranked &= time_to_collision >= longest - 1e-9 * max(1.0, longest)
    else:
        ranked &= time_to_collision == longest
    cheapest = np.min(costs[ranked])
    ranked &= costs <= cheapest + 1e-9 * max(1.0, abs(cheapest))
    ranked &= left_passes == np.min(left_passes[ranked])
    return int(np.argmin(np.where(ranked, costs, np.inf)))
