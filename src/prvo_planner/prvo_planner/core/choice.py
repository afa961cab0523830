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
# Chosen speeds stay this far (in t) inside a feasible interval so that rounding in the roots
# cannot put them on the rejected side.
INTERIOR = 1e-9


@dataclass(frozen=True)
class CostTerms:
    """
    The terms of the choice cost of one plan, or of one plan per row of velocities.

    Attributes
    ----------
    table : numpy.ndarray
        Shape (R, 8), R = 1 for one plan: per row ``v_pref`` (2), the previous command (2; any
        value where ``inertia`` is 0), ``inertia`` (the weight of ``|v - previous|``, 0 without a
        previous command), ``bias`` (the weight of ``max(0, left(v))``), ``progress`` (the share
        ``p`` of the goal term given to ``| |v_pref| - along(v) |``) and ``norm`` (``|v_pref|``,
        1 where ``bias`` and ``progress`` are 0); ``bias`` and ``progress`` are 0 when ``v_pref``
        has no direction.
    extra : numpy.ndarray
        Shape (R,): whether any term besides ``|v - v_pref|`` is on.

    """

    table: np.ndarray
    extra: np.ndarray

    @classmethod
    def of_plan(cls, v_pref, previous, config):
        """Return the terms of one plan."""
        inertia = config.inertia if previous is not None else 0.0
        norm = math.hypot(v_pref[0], v_pref[1])
        bias = config.passing_bias if norm > 1e-9 else 0.0
        progress = config.progress_weight if norm > 1e-9 else 0.0
        previous = v_pref if previous is None else previous
        return cls(table=np.array([[v_pref[0], v_pref[1], previous[0], previous[1], inertia, bias,
                                    progress, norm if bias > 0.0 or progress > 0.0 else 1.0]],
                                  dtype=np.float64),
                   extra=np.array([inertia > 0.0 or bias > 0.0 or progress > 0.0]))

    @classmethod
    def stacked(cls, terms, index):
        """Return per-row terms: row ``r`` is ``terms[index[r]]`` (a sequence of CostTerms)."""
        return cls(table=np.concatenate([term.table for term in terms])[index],
                   extra=np.concatenate([term.extra for term in terms])[index])

    def costs(self, velocities):
        """
        Cost of commanded velocities, shape (R, ..., 2) or, for one plan, (..., 2) -> (...).

        ``(1 - progress) |v - v_pref| + progress | |v_pref| - along(v) |`` (docs/method.md,
        section 7), plus ``inertia |v - previous|`` and ``bias max(0, left(v))``, with
        ``along`` and ``left`` the components of ``v`` along and to the left of ``v_pref``'s
        direction. The progress share charges only the speed lost towards the goal, not the
        speed sideways: it prefers passing a crowd at speed to slowing down behind it. Every
        term is convex in ``v`` and only ranks velocities; which ones are acceptable is decided
        by the constraints alone. A term of weight 0 adds exactly 0. Compiled
        (:func:`.choice_kernels.choice_costs`).
        """
        from .choice_kernels import choice_costs as compiled

        velocities = np.ascontiguousarray(velocities, dtype=np.float64)
        return compiled(velocities.reshape(-1, 2), self.table).reshape(velocities.shape[:-1])


def choice_costs(velocities, v_pref, previous, config):
    """Cost of commanded velocities of one plan, shape (..., 2) -> (...) (``CostTerms``)."""
    return CostTerms.of_plan(v_pref, previous, config).costs(velocities)


def cheapest_velocities(gap_ray, lower, upper, directions, rows, terms, max_speed):
    """
    Per plan the cheapest velocity over its feasible intervals, and its rays with one.

    Each interval's best ``t`` (kept :data:`INTERIOR` inside it) is the preferred ``t``
    projected onto it under the plain cost; the extra terms of :class:`CostTerms` keep the cost
    convex along the ray, so a grid zoomed onto the best point's cells finds it (the interval
    ends and the projection are candidates too), searched only on intervals that can hold their
    plan's optimum. A plan takes its first interval of the smallest cost. Compiled
    (:func:`.choice_kernels.cheapest_velocities`).

    Parameters
    ----------
    gap_ray, lower, upper : numpy.ndarray
        Feasible intervals (ray, lower, upper), shape (G,), grouped by plan.
    directions : numpy.ndarray
        Every ray's direction, shape (R, 2).
    rows : RayRows
        Each ray's plan (``ray_robot``), index among its plan's (``ray_local``) and preferred
        ``t`` (``preferred``).
    terms : CostTerms
        One row per plan (P rows).
    max_speed : numpy.ndarray
        ``v_max`` per plan, shape (P,).

    Returns
    -------
    feasible_rays, direction, t : numpy.ndarray
        Per plan its rays with a feasible interval, the chosen direction's index among its own
        (-1: none) and ``t``, shape (P,) each.

    """
    from .choice_kernels import cheapest_velocities as compiled

    return compiled(gap_ray, lower, upper, directions, rows.ray_robot, rows.ray_local,
                    rows.preferred, terms.table, terms.extra, max_speed, INTERIOR)


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

    Compiled: :func:`.choice_kernels.fallback_measures`.
    """
    from .choice_kernels import fallback_measures as compiled

    return compiled(np.ascontiguousarray(velocities, dtype=float),
                    np.ascontiguousarray(origin, dtype=float),
                    np.ascontiguousarray(lead, dtype=float),
                    np.ascontiguousarray(radius, dtype=float), float(horizon), float(period))


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
