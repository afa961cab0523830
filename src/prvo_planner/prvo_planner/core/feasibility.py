"""
Which speeds on each candidate ray meet the chance constraints, and by what margin.

``ray_gaps`` finds, for every direction, the intervals of ``t`` (speed ``t v_max``) where every
neighbour's accepted alternative holds with margin ``k``: closed-form roots of the mean and
``mean^2 - k^2 variance`` polynomials, Bernstein certificates per quarter of each ray, and one
sorted sweep over the rejected pieces. ``achieved_margins`` gives the ``k`` a velocity does reach
(reported when nothing is feasible), ``monte_carlo_probabilities`` the sampled baseline.
"""

from dataclasses import dataclass

import numpy as np

from .moments import reach_weights
from .probability import rvo_condition_of
from .ray_solver import (
    SEGMENTS,
    bernstein_minimum,
    polynomial_roots,
    quadratic_roots,
    segment_certificates,
    taylor_quadratics,
)


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
    alternatives is returned.

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
    sigma = np.maximum(variances, 0.0)
    np.sqrt(sigma, out=sigma)
    with np.errstate(divide='ignore', invalid='ignore'):
        # mean / 0 is +-inf as it should be; 0 / 0 (a zero mean known exactly) meets any k.
        margins = np.divide(means, sigma, out=sigma)
    margins[np.isnan(margins)] = np.inf
    result = margins[..., 0]
    if layout.has_receding:
        result = np.maximum(result, np.where(receding_enabled, margins[..., 1], -np.inf))
    if layout.has_horizon:
        joint = np.minimum(margins[..., -3], margins[..., -2])
        # sqrt((k'^2 - 1) / 2) for k' >= 1, else k' - 1, in place.
        pairwise = np.multiply(joint, joint)
        pairwise -= 1.0
        pairwise *= 0.5
        np.sqrt(pairwise, out=pairwise, where=joint >= 1.0)
        np.subtract(joint, 1.0, out=pairwise, where=joint < 1.0)
        result = np.maximum(result, pairwise)
        result = np.maximum(result, margins[..., -1])
    return result


def horner_coefficient_major(coefficients, t):
    """Evaluate polynomials with ascending coefficients along axis 0, shape (L, ...), at t."""
    value = coefficients[-1]
    for power in range(coefficients.shape[0] - 2, -1, -1):
        value = value * t + coefficients[power]
    return value


def _row_tests(mean_rows, variance_rows, margins_sq, method, deterministic, taylor_inputs):
    """
    Build the acceptance tests of every (neighbour, direction, condition) row.

    For the exact method ``mean - k sigma >= 0`` iff ``mean >= 0`` and ``mean^2 - k^2 var >= 0``
    (the quartic). Where the variance is certified positive on the ray, the surrogate changes
    only where ``mean = k sigma``, a root of the quartic, so the mean's roots bound pieces only
    where the variance may vanish (there the quartic has a double root at the mean's root,
    which closed-form roots resolve poorly).

    Parameters
    ----------
    mean_rows, variance_rows : numpy.ndarray
        Coefficient-major polynomials of the K rows, shapes (3, K) and (5, K).
    margins_sq : numpy.ndarray
        ``k^2`` per row, shape (K,).
    method, deterministic
        As for :func:`ray_gaps`.
    taylor_inputs : tuple
        ``(means, variances, margins, preferred)`` for :func:`taylor_quadratics` (rows last but
        one), used by the Taylor method only.

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray or None)
        Each test's coefficients, coefficient-major: shape (L, K) (acceptance needs every test
        ``>= 0``), with ``None``, or the variance polynomials (5, K) where a row's roots need
        not bound pieces if its variance is certified positive.

    """
    rows = mean_rows.shape[1]
    if deterministic:
        return [(mean_rows, None)]
    if method == 'taylor':
        quadratic = taylor_quadratics(*taylor_inputs)
        return [(np.moveaxis(quadratic, -1, 0).reshape(3, rows), None)]
    constant, linear, square = mean_rows
    quartic = np.empty((5, rows))
    np.multiply(constant, constant, out=quartic[0])
    np.multiply(constant, linear, out=quartic[1])
    quartic[1] *= 2.0
    np.multiply(constant, square, out=quartic[2])
    quartic[2] *= 2.0
    quartic[2] += linear * linear
    np.multiply(linear, square, out=quartic[3])
    quartic[3] *= 2.0
    np.multiply(square, square, out=quartic[4])
    quartic -= margins_sq * variance_rows
    return [(quartic, None), (mean_rows, variance_rows)]


def _relevant_conditions(reject_all, layout, receding_enabled):
    """
    Mark the conditions whose acceptance can change their pair's on a segment.

    A disabled ``g`` cannot, nor can ``h1`` (``h2``) when ``h2`` (``h1``) is rejected on the
    whole segment; their roots need not bound pieces.

    Parameters
    ----------
    reject_all : numpy.ndarray
        Per condition, rejected on the whole segment, shape (..., P, C).
    layout : ConditionLayout
        Column meaning.
    receding_enabled : numpy.ndarray
        Whether ``g`` counts, shape (P,).

    Returns
    -------
    numpy.ndarray
        Booleans, shape (..., P, C).

    """
    relevant = np.ones(reject_all.shape, dtype=bool)
    if layout.has_receding:
        relevant[..., 1] = receding_enabled
    if layout.has_horizon:
        relevant[..., -3] = ~reject_all[..., -2]
        relevant[..., -2] = ~reject_all[..., -3]
    return relevant


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


def _unit_cuts(unit_segment, values, slots):
    """
    Order every open unit's cuts: its segment's start, its roots ascending, its segment's end.

    A root lies in ``[start, end)`` of its segment (``t SEGMENTS`` is exact), so the order is
    that of sorting all of them by (unit, value), the segment's start first among equal values;
    only the roots need sorting.

    Parameters
    ----------
    unit_segment : numpy.ndarray
        Segment of each open unit, shape (U,).
    values, slots : numpy.ndarray
        The roots that cut units and the unit of each, shape (R,).

    Returns
    -------
    values, slots : numpy.ndarray
        Shape (2 U + R,): the cuts of unit 0, then of unit 1, ...

    """
    order = np.lexsort((values, slots))
    values, slots = values[order], slots[order]
    units = unit_segment.size
    roots_per_unit = np.bincount(slots, minlength=units)
    ends = np.cumsum(roots_per_unit + 2) - 1
    starts = ends - roots_per_unit - 1
    cut_values = np.empty(2 * units + values.size)
    cut_values[starts] = unit_segment / SEGMENTS
    cut_values[ends] = (unit_segment + 1) / SEGMENTS
    first_root = np.cumsum(roots_per_unit) - roots_per_unit
    cut_values[starts[slots] + 1 + np.arange(values.size) - first_root[slots]] = values
    return cut_values, np.repeat(np.arange(units), roots_per_unit + 2)


def team_ray_gaps(rows, layout, method, deterministic):
    """
    Feasible speed intervals on every ray: the intersection over neighbours of accepted sets.

    Rays are split into ``SEGMENTS`` equal segments of ``t``. A segment that some neighbour
    rejects entirely (a Bernstein certificate) is closed; on every other segment, each
    (neighbour, direction) link whose acceptance is not certified there is cut at the roots of
    its tests that fall in the segment; each piece is accepted or not by its midpoint, and the
    rejected pieces and closed segments of each ray are swept in one sort. Every value of a
    ray is computed by the same operations whatever the other rays in the call, so a robot's
    intervals do not depend on which robots are planned with it.

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

    Returns
    -------
    ray : numpy.ndarray
        Ray index of each feasible interval, shape (G,), non-decreasing in robot.
    lower, upper : numpy.ndarray
        Interval ends in ``t``, shape (G,), ``lower < upper``.

    """
    links, conditions = rows.means.shape[:2]
    ray_count = rows.ray_local.shape[0]
    count = links * conditions
    # Free reshapes of coefficient-major polynomials.
    mean_rows = rows.means.transpose(2, 0, 1).reshape(3, count)
    variance_rows = rows.variances.transpose(2, 0, 1).reshape(5, count)
    margins = np.ascontiguousarray(rows.margins)
    tests = _row_tests(mean_rows, variance_rows, (margins ** 2).reshape(count), method,
                       deterministic, (rows.means, rows.variances, margins,
                                       rows.preferred[rows.link_ray][:, None]))
    # Per (segment, row): (S, K), viewed as (S, P, C).
    certificates = [segment_certificates(test) for test, _ in tests]
    accept, reject = certificates[0]
    for nonnegative, negative in certificates[1:]:
        accept, reject = accept & nonnegative, reject | negative
    enabled = rows.link_enabled
    accept = accept.reshape(SEGMENTS, links, conditions)
    reject = reject.reshape(SEGMENTS, links, conditions)
    accept_pair = combine_conditions(accept, layout, enabled)
    reject_pair = ~combine_conditions(~reject, layout, enabled)
    # A segment of a ray is open unless some neighbour rejects all of it: (S, R).
    segment_ray = (np.arange(SEGMENTS)[:, None] * ray_count + rows.link_ray).ravel()
    open_segments = np.bincount(segment_ray[reject_pair.ravel()],
                                minlength=SEGMENTS * ray_count).reshape(SEGMENTS, -1) == 0
    open_rays = open_segments.any(axis=0)
    # Units: (segment, link) on an open segment, not certified accepted there; flat s P + p.
    open_unit = (~accept_pair & open_segments[:, rows.link_ray]).ravel()
    open_index = open_unit.nonzero()[0]
    unit_slot = np.zeros(open_unit.size, dtype=int)
    unit_slot[open_index] = np.arange(open_index.size)
    # Only a condition undecided on a segment can split it, and only where its own test is.
    splitting = (~(accept | reject) & _relevant_conditions(reject, layout, enabled)
                 & open_unit.reshape(SEGMENTS, links, 1))
    # g's quartic is a quadratic: its mean is linear and its variance quadratic in t.
    quadratic_condition = np.zeros(conditions, dtype=bool)
    quadratic_condition[1:2] = layout.has_receding
    # Every open unit's cuts inside its segment, flat: cut values and the open unit (slot)
    # each belongs to.
    cut_values, cut_slots = [np.empty(0)], [np.empty(0, dtype=int)]
    for (test, test_variances), (nonnegative, negative) in zip(tests, certificates,
                                                               strict=True):
        undecided = splitting & ~(nonnegative | negative).reshape(SEGMENTS, links, conditions)
        needed = undecided.any(axis=0)
        quadratic_rows = needed & quadratic_condition
        for selected, quartic in ((needed & ~quadratic_condition, test.shape[0] == 5),
                                  (quadratic_rows, False)):
            row = selected.ravel().nonzero()[0]
            if test_variances is not None and row.size:
                # Quiet rows: a variance certified positive needs no cuts at this test's roots.
                row = row[bernstein_minimum(np.take(test_variances, row, axis=1)) <= 0.0]
            if not row.size:
                continue
            columns = np.take(test, row, axis=1)
            roots = (polynomial_roots(columns) if quartic else
                     quadratic_roots(columns[0], columns[1], columns[2]))
            # A root cuts the unit of the segment it falls in, if the row splits that one.
            inside = (roots > 0.0) & (roots < 1.0)
            values = roots[inside]
            segment = np.minimum((values * SEGMENTS).astype(int), SEGMENTS - 1)
            root_row = np.broadcast_to(row[:, None], roots.shape)[inside]
            cuts = undecided.reshape(SEGMENTS, -1)[segment, root_row]
            cut_values.append(values[cuts])
            cut_slots.append(unit_slot[segment[cuts] * links + root_row[cuts] // conditions])
    cut_values, cut_slots = _unit_cuts(open_index // links, np.concatenate(cut_values),
                                       np.concatenate(cut_slots))
    piece = cut_slots[1:] == cut_slots[:-1]
    piece_start, piece_end = cut_values[:-1][piece], cut_values[1:][piece]
    piece_link = open_index[cut_slots[:-1][piece]] % links
    midpoints = (0.5 * (piece_start + piece_end))[:, None]
    accepted = True
    for test, _ in tests:
        # (L, pieces, C): each piece's link's coefficients; Horner's rule at its midpoint.
        value = horner_coefficient_major(
            np.take(test.reshape(test.shape[0], links, conditions), piece_link, axis=1),
            midpoints)
        accepted = accepted & (value >= 0.0)
    accepted = combine_conditions(accepted, layout, enabled[piece_link])
    # Sweep the rejected pieces and closed segments of each open ray, shifted by 4 per
    # direction of its robot so that one sort handles every ray; sentinels reject t < 0 and
    # t > 1 and end where the next ray's first sentinel starts, so no gap spans two rays.
    rejected = ~accepted
    closed_segment, closed_ray = (~open_segments & open_rays).nonzero()
    sentinel_ray = open_rays.nonzero()[0]
    ray = np.concatenate([rows.link_ray[piece_link[rejected]], closed_ray, sentinel_ray,
                          sentinel_ray])
    shift = 4.0 * rows.ray_local[ray]
    sentinels = sentinel_ray.size
    starts = np.concatenate([piece_start[rejected], closed_segment / SEGMENTS,
                             np.full(sentinels, -1.0), np.ones(sentinels)]) + shift
    ends = np.concatenate([piece_end[rejected], (closed_segment + 1) / SEGMENTS,
                           np.zeros(sentinels), np.full(sentinels, 3.0)]) + shift
    robot = rows.ray_robot[ray]
    order = np.lexsort((starts, robot))
    starts, ray, ends, robot = starts[order], ray[order], ends[order], robot[order]
    # The running end of the rejected set, restarted for every robot.
    reach = np.empty_like(ends)
    bounds = np.flatnonzero(np.diff(robot)) + 1
    for first, last in zip(np.concatenate([[0], bounds]), np.concatenate([bounds, [ray.size]]),
                           strict=True):
        np.maximum.accumulate(ends[first:last], out=reach[first:last])
    valid = (starts[1:] > reach[:-1]) & (ray[1:] == ray[:-1])
    ray = ray[1:][valid]
    local_shift = 4.0 * rows.ray_local[ray]
    return ray, reach[:-1][valid] - local_shift, starts[1:][valid] - local_shift


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
