"""
Which speeds on each candidate ray meet the chance constraints, and by what margin.

``ray_gaps`` finds, for every direction, the intervals of ``t`` (speed ``t v_max``) where every
neighbour's accepted alternative holds with margin ``k``: closed-form roots of the mean and
``mean^2 - k^2 variance`` polynomials, Bernstein certificates per quarter of each ray, and one
sorted sweep over the rejected pieces. ``achieved_margins`` gives the ``k`` a velocity does reach
(reported when nothing is feasible), ``monte_carlo_probabilities`` the sampled baseline.
"""

from dataclasses import dataclass
import math

import numpy as np

from .moments import reach_weights
from .probability import rvo_condition_of


def combine_conditions(per_condition, layout, receding_enabled, any_of=np.logical_or,
                       all_of=np.logical_and):
    """
    Combine per-condition values into ``f or g or (h1 and h2) or h3``.

    Parameters
    ----------
    per_condition : numpy.ndarray
        Shape (..., C): booleans, or margins with ``any_of=np.maximum, all_of=np.minimum``.
    layout : ConditionLayout
        Column meaning.
    receding_enabled : numpy.ndarray
        Whether ``g`` counts, broadcastable to shape (...).
    any_of, all_of : callable
        The binary "or" and "and".

    Returns
    -------
    numpy.ndarray
        Shape (...).

    """
    result = per_condition[..., 0]
    if layout.has_receding:
        disabled = False if per_condition.dtype == bool else -np.inf
        result = any_of(result, np.where(receding_enabled, per_condition[..., 1], disabled))
    if layout.has_horizon:
        result = any_of(result, all_of(per_condition[..., -3], per_condition[..., -2]))
        result = any_of(result, per_condition[..., -1])
    return result


def achieved_margins(means, variances, layout, receding_enabled):
    """
    Achieved ``k`` at given points (docs/method.md, section 7: no accepted velocity).

    Per condition the achieved ``k`` is ``mean / sigma`` (``+-inf`` when ``sigma = 0``). The
    pair ``h1 and h2`` meets ``k' = min(k_h1, k_h2)``, which is reported as the pairwise ``k``
    with that ``k'``: ``sqrt((k'^2 - 1) / 2)`` (and ``k' - 1 < 0`` below ``k' = 1``, where the
    pair bounds nothing); ``h3`` alone meets its own. The largest over the accepted
    alternatives is returned. Compiled (:func:`prvo_planner.core.ray_search.achieved_margins`).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition values at the points, shape (..., C).
    layout : ConditionLayout
        Column meaning.
    receding_enabled : numpy.ndarray
        Whether ``g`` counts, broadcastable to shape (...).

    Returns
    -------
    numpy.ndarray
        Shape (...).

    """
    from .ray_search import achieved_margins as margins

    conditions = means.shape[-1]
    shape = np.broadcast_shapes(means.shape[:-1], variances.shape[:-1],
                                np.shape(receding_enabled))
    count = math.prod(shape)
    return margins(*(np.ascontiguousarray(np.broadcast_to(values, shape + (conditions,)),
                                          dtype=np.float64).reshape(count, conditions)
                     for values in (means, variances)),
                   np.ascontiguousarray(np.broadcast_to(receding_enabled, shape),
                                        dtype=np.bool_).reshape(count),
                   bool(layout.has_receding), bool(layout.has_horizon)).reshape(shape)


def ray_gaps(means, variances, margins, layout, method, deterministic, preferred):
    """
    Feasible speed intervals on every ray of one plan (:func:`team_ray_gaps` for one robot).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition polynomials, shapes (N, M, C, 3) and (N, M, C, 5), laid out
        coefficient-major (as :func:`prvo_planner.core.moments.ray_polynomials` returns them).
    margins : numpy.ndarray
        ``k`` per condition column, shape (C,).
    layout : ConditionLayout
        Column meaning.
    method : str
        ``'exact'`` or ``'taylor'``.
    deterministic : bool
        All variances are zero (the mean alone decides).
    preferred : numpy.ndarray
        Preferred ``t`` per direction, shape (M,).

    Returns
    -------
    direction : numpy.ndarray
        Direction index of each feasible interval, shape (G,).
    lower, upper : numpy.ndarray
        Interval ends in ``t``, shape (G,), ``lower < upper``.

    """
    count, directions, conditions = means.shape[:3]
    rows = RayRows(
        means=means.reshape(count * directions, conditions, 3),
        variances=variances.reshape(count * directions, conditions, 5),
        margins=np.broadcast_to(margins, (count * directions, conditions)),
        link_ray=np.tile(np.arange(directions), count),
        link_enabled=np.repeat(layout.receding_enabled, directions),
        ray_local=np.arange(directions), ray_robot=np.zeros(directions, dtype=int),
        preferred=preferred)
    return team_ray_gaps(rows, layout, method, deterministic)


@dataclass(frozen=True)
class RayRows:
    """
    The (neighbour, direction) links of one or several plans, and the rays they lie on.

    Links of one robot are contiguous and ordered (neighbour, direction), the robots' rays in
    order; the polynomials are views of coefficient-major memory.

    Attributes
    ----------
    means, variances : numpy.ndarray
        Condition polynomials per link, shapes (P, C, 3) and (P, C, 5).
    margins : numpy.ndarray
        ``k`` per link and condition column, shape (P, C).
    link_ray : numpy.ndarray
        Ray of each link, shape (P,).
    link_enabled : numpy.ndarray
        Whether ``g`` counts for each link's neighbour, shape (P,).
    ray_local : numpy.ndarray
        Index of each ray among its robot's directions, shape (R,).
    ray_robot : numpy.ndarray
        Robot of each ray, non-decreasing, shape (R,).
    preferred : numpy.ndarray
        Preferred ``t`` per ray, shape (R,).

    """

    means: np.ndarray
    variances: np.ndarray
    margins: np.ndarray
    link_ray: np.ndarray
    link_enabled: np.ndarray
    ray_local: np.ndarray
    ray_robot: np.ndarray
    preferred: np.ndarray


def team_ray_gaps(rows, layout, method, deterministic, searched=None):
    """
    Feasible speed intervals on every ray: the intersection over neighbours of accepted sets.

    Rays are split into 4 equal segments of ``t``. A segment that some neighbour rejects
    entirely (a Bernstein certificate) is closed; on every other segment, each (neighbour,
    direction) link whose acceptance is not certified there is cut at the roots of its tests
    that fall in the segment; each piece is accepted or not by its midpoint, and the rejected
    pieces and closed segments of each ray are swept in order. Every value of a ray is computed
    by the same operations whatever the other rays in the call, so a robot's intervals do not
    depend on which robots are planned with it. The search is compiled
    (:func:`prvo_planner.core.ray_search.team_gaps`, imported, and so loaded or compiled, on
    the first call).

    Parameters
    ----------
    rows : RayRows
        The links and rays.
    layout : ConditionLayout
        Column meaning (shared by every robot of the call).
    method : str
        ``'exact'`` or ``'taylor'``.
    deterministic : bool
        All variances are zero (the mean alone decides).
    searched : numpy.ndarray, optional
        Per robot, whether its rays are searched (the others get no interval), shape (B,);
        default all.

    Returns
    -------
    ray : numpy.ndarray
        Ray index of each feasible interval, shape (G,), non-decreasing in robot.
    lower, upper : numpy.ndarray
        Interval ends in ``t``, shape (G,), ``lower < upper``.

    """
    from .ray_search import team_gaps

    links, conditions = rows.means.shape[:2]
    count = links * conditions
    # Free reshapes of coefficient-major polynomials.
    means = np.ascontiguousarray(rows.means.transpose(2, 0, 1).reshape(3, count),
                                 dtype=np.float64)
    variances = np.ascontiguousarray(rows.variances.transpose(2, 0, 1).reshape(5, count),
                                     dtype=np.float64)
    margins = np.ascontiguousarray(rows.margins, dtype=np.float64).reshape(count)
    if searched is None:
        searched = np.ones(np.count_nonzero(rows.ray_local == 0), dtype=np.bool_)
    return team_gaps(
        means, variances, margins, np.ascontiguousarray(rows.link_ray, dtype=np.int64),
        np.ascontiguousarray(rows.link_enabled, dtype=np.bool_),
        np.ascontiguousarray(rows.ray_local, dtype=np.int64),
        np.ascontiguousarray(rows.preferred, dtype=np.float64), conditions,
        bool(layout.has_receding), bool(layout.has_horizon), method == 'taylor',
        bool(deterministic), np.ascontiguousarray(searched, dtype=np.bool_))


def monte_carlo_probabilities(encounter, layout, directions, speeds, config, rng):
    """
    Per neighbour, the sampled probability that the accepted event holds at each candidate.

    Parameters
    ----------
    encounter : Encounter
        Neighbours.
    layout : ConditionLayout
        Which alternatives are accepted.
    directions : numpy.ndarray
        Shape (M, 2).
    speeds : numpy.ndarray
        ``t`` per direction, shape (M, T).
    config : PlannerConfig
        ``mc_samples``, ``max_speed``, ``time_horizon``.
    rng : numpy.random.Generator
        Source of samples.

    Returns
    -------
    numpy.ndarray
        Shape (N, M, T).

    """
    command = config.max_speed * speeds[..., None] * directions[:, None, :]
    weights = reach_weights(encounter.origin, encounter.combined_radius)
    probabilities = []
    for index in range(encounter.origin.shape[0]):
        velocity = encounter.lead[index] * command
        eigenvalues, eigenvectors = np.linalg.eigh(encounter.cov[index])
        root = eigenvectors * np.sqrt(np.maximum(eigenvalues, 0.0))
        z = encounter.origin[index] + rng.standard_normal((config.mc_samples, 4)) @ root.T
        rel_x, rel_y = z[:, 0], z[:, 1]
        u_x = z[:, 2] + velocity[..., 0, None]
        u_y = z[:, 3] + velocity[..., 1, None]
        radius_sq = encounter.combined_radius[index] ** 2
        speed_sq = u_x * u_x + u_y * u_y
        event = rvo_condition_of(rel_x, rel_y, u_x, u_y, encounter.combined_radius[index]) >= 0.0
        closing = rel_x * u_x + rel_y * u_y
        if layout.receding_enabled[index]:
            event |= closing >= 0.0
        if layout.has_horizon:
            tau = config.time_horizon
            event |= ((-closing - tau * speed_sq >= 0.0)
                      & ((rel_x + tau * u_x) ** 2 + (rel_y + tau * u_y) ** 2 >= radius_sq))
            weight = weights[index]
            event |= ((1.0 - weight) * (rel_x * rel_x + rel_y * rel_y
                                        - tau * tau * speed_sq / weight) >= radius_sq)
        probabilities.append(np.mean(event, axis=-1))
    return np.array(probabilities)
