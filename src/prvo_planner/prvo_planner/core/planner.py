"""
The PRVO velocity planner and its baselines (prvo-math.md sections 5 to 9).

One call builds, for every (neighbour, candidate direction) pair, the mean and variance
polynomials of every condition in the ray parameter ``t`` (speed ``t v_max``), finds each pair's
accepted speeds in closed form, intersects them per direction by a sorted sweep over the
rejected pieces, and picks the feasible velocity closest to the preferred one. Everything is
vectorised over neighbours and directions.
"""

from dataclasses import dataclass
import functools
import math

import numpy as np

from .beliefs import AgentBelief, as_finite_array
from .config import PlannerConfig, PlanResult
from .moments import condition_moments, poly_eval, ray_polynomials
from .probability import eta_from_k
from .ray_solver import (
    SEGMENTS,
    bernstein_minimum,
    polynomial_roots,
    quadratic_roots,
    segment_certificates,
    taylor_quadratics,
)

# Speeds, as fractions of v_max, tried on every direction when no direction is feasible (and by
# the Monte Carlo baseline), besides the preferred speed on the direction.
_SPEED_GRID = np.linspace(0.0, 1.0, 9)
_SPEED_GRID_POWERS = _SPEED_GRID[:, None] ** np.arange(5)
# The best speed on a ray under the inertia / passing-bias cost: a grid of 17 points over the
# interval, zoomed 5 times onto the best point's two cells (1/8 of the span each time): to
# 8^-5 (3e-5) of the interval.
_ZOOM_GRID = np.linspace(0.0, 1.0, 17)
_ZOOM_LEVELS = 5
# Chosen speeds stay this far (in t) inside a feasible interval so that rounding in the roots
# cannot put them on the rejected side.
_INTERIOR = 1e-9
# Relative floor on sigma used only to rank infeasible candidates of noise-free models.
_RANK_FLOOR = 1e-6


@dataclass(frozen=True)
class Encounter:
    """
    The neighbours a plan considers, as relative Gaussians (prvo-math.md section 2).

    Attributes
    ----------
    origin : numpy.ndarray
        Mean of ``z = (r, u)`` at zero command, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z`` (with ``4 S_a`` in the velocity block), shape (N, 4, 4).
    combined_radius : numpy.ndarray
        ``R = R_i + R_j + margin``, shape (N,).
    overlapping : numpy.ndarray
        Whether the mean centres are closer than ``R``, shape (N,).
    margin : float
        Per-neighbour ``k`` for ``f`` and ``g``.
    horizon_margin : float
        Per-neighbour ``k'`` for each of ``h1`` and ``h2``.
    eta : float
        Per-neighbour probability in force.

    """

    origin: np.ndarray
    cov: np.ndarray
    combined_radius: np.ndarray
    overlapping: np.ndarray
    margin: float
    horizon_margin: float
    eta: float


def build_encounter(ego, neighbours, config):
    """
    Select the neighbours within ``neighbor_distance`` and form their relative Gaussians.

    The distance is between the mean disk surfaces: ``|p_i - p_j| - R_i - R_j``.

    Parameters
    ----------
    ego : AgentBelief
        The planning robot.
    neighbours : sequence of AgentBelief
        Other robots.
    config : PlannerConfig
        Planner parameters.

    Returns
    -------
    Encounter
        The selected neighbours (possibly none).

    """
    positions = np.array([belief.position for belief in neighbours]).reshape(-1, 2)
    velocities = np.array([belief.velocity for belief in neighbours]).reshape(-1, 2)
    covariances = np.array([belief.covariance for belief in neighbours]).reshape(-1, 4, 4)
    radii = np.array([belief.radius for belief in neighbours])
    relative_position = ego.position - positions
    distance = np.hypot(relative_position[:, 0], relative_position[:, 1])
    near = distance - ego.radius - radii <= config.neighbor_distance
    count = int(near.sum())
    margin = config.effective_k
    if config.risk == 'joint' and count > 0:
        # 1 - eta_j = (1 - eta) / n with 1 - eta = 1 / (1 + k^2), written in k to stay finite.
        margin = math.sqrt((1.0 + margin ** 2) * count - 1.0)
    cov = np.zeros((count, 4, 4))
    cov[:, :2, :2] = ego.covariance[:2, :2] + covariances[near, :2, :2]
    cov[:, 2:, 2:] = (4.0 * config.actuation_cov + ego.covariance[2:, 2:]
                      + covariances[near, 2:, 2:])
    cross = -ego.covariance[:2, 2:] + covariances[near, :2, 2:]
    cov[:, :2, 2:] = cross
    cov[:, 2:, :2] = cross.swapaxes(-1, -2)
    combined_radius = ego.radius + radii[near] + config.safety_margin
    return Encounter(
        origin=np.concatenate([relative_position[near], -ego.velocity - velocities[near]], axis=1),
        cov=cov, combined_radius=combined_radius,
        overlapping=distance[near] < combined_radius, margin=margin,
        # k' = sqrt((1 + eta) / (1 - eta)) with eta = k^2 / (1 + k^2).
        horizon_margin=math.sqrt(1.0 + 2.0 * margin ** 2), eta=eta_from_k(margin))


@functools.lru_cache(maxsize=16)
def _headings(count, seed):
    """``count`` evenly spaced unit headings, rotated by a random offset when seeded (M, 2)."""
    offset = 0.0
    if seed is not None:
        offset = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi / count)
    headings = offset + 2.0 * np.pi * np.arange(count) / count
    directions = np.stack([np.cos(headings), np.sin(headings)], axis=1)
    # Shared between calls: read-only so that no caller can alter the cached value.
    directions.flags.writeable = False
    return directions


def candidate_directions(ego, v_pref, config):
    """
    Return unit candidate directions: ``v_pref``'s, the current velocity's, ``M`` headings.

    Parameters
    ----------
    ego : AgentBelief
        Supplies the current (mean) velocity.
    v_pref : numpy.ndarray
        Preferred velocity, shape (2,).
    config : PlannerConfig
        ``num_directions`` and ``seed`` (a seed rotates the headings by a random offset).

    Returns
    -------
    numpy.ndarray
        Shape (M', 2) with M' in [M, M + 2].

    """
    directions = [_headings(config.num_directions, config.seed)]
    for vector in (ego.velocity, v_pref):
        norm = math.hypot(vector[0], vector[1])
        if norm > 1e-9:
            directions.insert(0, (vector / norm)[None, :])
    return np.concatenate(directions, axis=0)


@dataclass(frozen=True)
class ConditionLayout:
    """
    Which conditions each neighbour has, in the column order of ``condition_moments``.

    Attributes
    ----------
    has_receding : bool
        A ``g`` column exists (index 1).
    has_horizon : bool
        ``h1`` and ``h2`` columns exist (the last two).
    receding_enabled : numpy.ndarray
        Per neighbour, whether ``g`` is accepted, shape (N,).

    """

    has_receding: bool
    has_horizon: bool
    receding_enabled: np.ndarray

    def margins(self, encounter):
        """Return the ``k`` of each condition column (``k'`` for ``h1``, ``h2``), shape (C,)."""
        return np.array([encounter.margin] * (1 + self.has_receding)
                        + [encounter.horizon_margin] * (2 * self.has_horizon))


def condition_layout(encounter, config):
    """Conditions for an encounter: ``g`` is always on for overlapping neighbours (f < 0)."""
    enabled = np.full(encounter.overlapping.shape, config.receding_gate) | encounter.overlapping
    return ConditionLayout(has_receding=bool(enabled.any()),
                           has_horizon=math.isfinite(config.time_horizon),
                           receding_enabled=enabled)


def combine_conditions(per_condition, layout, receding_enabled, any_of=np.logical_or,
                       all_of=np.logical_and):
    """
    Combine per-condition values into ``f or g or (h1 and h2)``.

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
        result = any_of(result, all_of(per_condition[..., -2], per_condition[..., -1]))
    return result


def achieved_margins(means, variances, layout, receding_enabled, rank=False, scratch=False):
    """
    Achieved ``k`` at given points (prvo-math.md section 7, no feasible velocity).

    Per condition the achieved ``k`` is ``mean / sigma`` (``+-inf`` when ``sigma = 0``). The
    pair ``h1 and h2`` meets ``k' = min(k_h1, k_h2)``, which is reported as the pairwise ``k``
    with that ``k'``: ``sqrt((k'^2 - 1) / 2)`` (and ``k' - 1 < 0`` below ``k' = 1``, where the
    pair bounds nothing). The largest over the accepted alternatives is returned.

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition values at the points, shape (..., C).
    layout : ConditionLayout
        Column meaning.
    receding_enabled : numpy.ndarray
        Whether ``g`` counts, broadcastable to shape (...).
    rank : bool
        Floor ``sigma`` relative to the mean's size, so that noise-free candidates are ranked
        by their normalised margin instead of tying at ``-inf``.
    scratch : bool
        ``variances`` is a temporary that may be overwritten (saves a copy of a large grid).

    Returns
    -------
    numpy.ndarray
        Shape (...).

    """
    sigma = np.maximum(variances, 0.0, out=variances if scratch else None)
    if rank:
        # sqrt of a sum, not np.hypot: the same floor at a fraction of the cost; in place, as
        # the grid of candidates can be large.
        floor = np.multiply(means, _RANK_FLOOR)
        floor *= floor
        sigma += floor
    np.sqrt(sigma, out=sigma)
    with np.errstate(divide='ignore', invalid='ignore'):
        # mean / 0 is +-inf as it should be; 0 / 0 (a zero mean known exactly) meets any k.
        margins = np.divide(means, sigma, out=sigma)
    margins[np.isnan(margins)] = np.inf
    result = margins[..., 0]
    if layout.has_receding:
        result = np.maximum(result, np.where(receding_enabled, margins[..., 1], -np.inf))
    if layout.has_horizon:
        joint = np.minimum(margins[..., -2], margins[..., -1])
        # sqrt((k'^2 - 1) / 2) for k' >= 1, else k' - 1; in place, as the grid can be large.
        pairwise = np.multiply(joint, joint)
        pairwise -= 1.0
        pairwise *= 0.5
        np.sqrt(pairwise, out=pairwise, where=joint >= 1.0)
        np.subtract(joint, 1.0, out=pairwise, where=joint < 1.0)
        result = np.maximum(result, pairwise)
    return result


def _horner_coefficient_major(coefficients, t):
    """Evaluate polynomials with ascending coefficients along axis 0, shape (L, ...), at t."""
    value = coefficients[-1]
    for power in range(coefficients.shape[0] - 2, -1, -1):
        value = value * t + coefficients[power]
    return value


def _row_tests(means, variances, margins, method, deterministic, preferred):
    """
    Build the acceptance tests of every (neighbour, direction, condition) row.

    For the exact method ``mean - k sigma >= 0`` iff ``mean >= 0`` and ``mean^2 - k^2 var >= 0``
    (the quartic). Where the variance is certified positive on the ray, the surrogate changes
    only where ``mean = k sigma``, a root of the quartic, so the mean's roots bound pieces only
    where the variance may vanish (there the quartic has a double root at the mean's root,
    which closed-form roots resolve poorly).

    Parameters
    ----------
    means, variances, margins, method, deterministic, preferred
        As for :func:`ray_gaps`.

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray or None)
        Each test's coefficients, coefficient-major: shape (L, K) over the K = N M C rows in
        (neighbour, direction, condition) order (acceptance needs every test ``>= 0``), with
        ``None``, or the variance polynomials (5, K) where a row's roots need not bound pieces
        if its variance is certified positive.

    """
    rows = means.shape[0] * means.shape[1] * means.shape[2]
    # Free reshapes when the polynomials are laid out coefficient-major (ray_polynomials).
    mean_rows = means.transpose(3, 0, 1, 2).reshape(3, rows)
    if deterministic:
        return [(mean_rows, None)]
    if method == 'taylor':
        quadratic = taylor_quadratics(means, variances, margins, preferred[None, :, None])
        return [(np.moveaxis(quadratic, -1, 0).reshape(3, rows), None)]
    variance_rows = variances.transpose(3, 0, 1, 2).reshape(5, rows)
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
    # Rows cycle through the conditions fastest: k^2 broadcasts over (5, rows / C, C).
    quartic.reshape(5, -1, margins.size)[...] -= (
        margins ** 2 * variance_rows.reshape(5, -1, margins.size))
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
        relevant[..., -2] = ~reject_all[..., -1]
        relevant[..., -1] = ~reject_all[..., -2]
    return relevant


def ray_gaps(means, variances, margins, layout, method, deterministic, preferred):
    """
    Feasible speed intervals on every ray: the intersection over neighbours of accepted sets.

    Rays are split into ``SEGMENTS`` equal segments of ``t``. A segment that some neighbour
    rejects entirely (a Bernstein certificate) is closed; on every other segment, each
    (neighbour, direction) pair whose acceptance is not certified there is cut at the roots of
    its tests that fall in the segment; each piece is accepted or not by its midpoint, and the
    rejected pieces and closed segments of each direction are swept in one sort.

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition polynomials, shapes (N, M, C, 3) and (N, M, C, 5).
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
    pairs = count * directions
    tests = _row_tests(means, variances, margins, method, deterministic, preferred)
    # Per (segment, row): (S, K), viewed as (S, P, C).
    certificates = [segment_certificates(test) for test, _ in tests]
    accept, reject = certificates[0]
    for nonnegative, negative in certificates[1:]:
        accept, reject = accept & nonnegative, reject | negative
    enabled = np.repeat(layout.receding_enabled, directions)
    accept = accept.reshape(SEGMENTS, pairs, conditions)
    reject = reject.reshape(SEGMENTS, pairs, conditions)
    accept_pair = combine_conditions(accept, layout, enabled)
    reject_pair = ~combine_conditions(~reject, layout, enabled)
    # A segment of a direction is open unless some neighbour rejects all of it: (S, M).
    open_segments = ~reject_pair.reshape(SEGMENTS, count, directions).any(axis=1)
    open_directions = open_segments.any(axis=0)
    # Units: (segment, pair) on an open segment, not certified accepted there; flat s P + p.
    open_unit = (~accept_pair & np.tile(open_segments, count)).ravel()
    open_index = open_unit.nonzero()[0]
    unit_slot = np.zeros(open_unit.size, dtype=int)
    unit_slot[open_index] = np.arange(open_index.size)
    # Only a condition undecided on a segment can split it, and only where its own test is.
    splitting = (~(accept | reject) & _relevant_conditions(reject, layout, enabled)
                 & open_unit.reshape(SEGMENTS, pairs, 1))
    # g's quartic is a quadratic: its mean is linear and its variance quadratic in t.
    quadratic_condition = np.zeros(conditions, dtype=bool)
    quadratic_condition[1:2] = layout.has_receding
    # Every open unit's cuts, flat, with its segment's ends as the ends of its first and last
    # pieces: cut values and the open unit (slot) each belongs to.
    unit_segment = open_index // pairs
    cut_values = [unit_segment / SEGMENTS, (unit_segment + 1) / SEGMENTS]
    cut_slots = [np.arange(open_index.size)] * 2
    for (test, variance_rows), (nonnegative, negative) in zip(tests, certificates, strict=True):
        undecided = splitting & ~(nonnegative | negative).reshape(SEGMENTS, pairs, conditions)
        needed = undecided.any(axis=0)
        quadratic_rows = needed & quadratic_condition
        for rows, quartic in ((needed & ~quadratic_condition, test.shape[0] == 5),
                              (quadratic_rows, False)):
            row = rows.ravel().nonzero()[0]
            if variance_rows is not None and row.size:
                # Quiet rows: a variance certified positive needs no cuts at this test's roots.
                row = row[bernstein_minimum(np.take(variance_rows, row, axis=1)) <= 0.0]
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
            cut_slots.append(unit_slot[segment[cuts] * pairs + root_row[cuts] // conditions])
    cut_values = np.concatenate(cut_values)
    cut_slots = np.concatenate(cut_slots)
    order = np.lexsort((cut_values, cut_slots))
    cut_values, cut_slots = cut_values[order], cut_slots[order]
    piece = cut_slots[1:] == cut_slots[:-1]
    piece_start, piece_end = cut_values[:-1][piece], cut_values[1:][piece]
    piece_pair = open_index[cut_slots[:-1][piece]] % pairs
    midpoints = (0.5 * (piece_start + piece_end))[:, None]
    accepted = True
    for test, _ in tests:
        # (L, pieces, C): each piece's pair's coefficients; Horner's rule at its midpoint.
        value = _horner_coefficient_major(
            np.take(test.reshape(test.shape[0], pairs, conditions), piece_pair, axis=1),
            midpoints)
        accepted = accepted & (value >= 0.0)
    accepted = combine_conditions(accepted, layout, enabled[piece_pair])
    # Sweep the rejected pieces and closed segments of each open direction, shifted by 4 per
    # direction so that one sort handles every direction; sentinels reject t < 0 and t > 1 and
    # end where the next direction's first sentinel starts, so no gap spans two directions.
    rejected = ~accepted
    closed_segment, closed_direction = (~open_segments & open_directions).nonzero()
    sentinel_direction = open_directions.nonzero()[0]
    direction = np.concatenate([piece_pair[rejected] % directions, closed_direction,
                                sentinel_direction, sentinel_direction])
    shift = 4.0 * direction
    sentinels = sentinel_direction.size
    starts = np.concatenate([piece_start[rejected], closed_segment / SEGMENTS,
                             np.full(sentinels, -1.0), np.ones(sentinels)]) + shift
    ends = np.concatenate([piece_end[rejected], (closed_segment + 1) / SEGMENTS,
                           np.zeros(sentinels), np.full(sentinels, 3.0)]) + shift
    order = np.argsort(starts, kind='stable')
    starts, direction = starts[order], direction[order]
    reach = np.maximum.accumulate(ends[order])
    valid = (starts[1:] > reach[:-1]) & (direction[1:] == direction[:-1])
    direction = direction[1:][valid]
    return direction, reach[:-1][valid] - 4.0 * direction, starts[1:][valid] - 4.0 * direction


def _model_moments(encounter, config):
    """Covariance and radius the model plans with, and whether it is noise-free."""
    if config.model in ('prvo', 'mc'):
        # Exactly known beliefs make every variance zero: the means alone decide.
        return encounter.cov, encounter.combined_radius, not encounter.cov.any()
    radius = encounter.combined_radius
    if config.model == 'inflate':
        position_spread = np.linalg.eigvalsh(encounter.cov[:, :2, :2])[:, -1]
        # c = sqrt(-2 ln(1 - eta)) with 1 - eta = 1 / (1 + k^2).
        confidence = math.sqrt(2.0 * math.log1p(encounter.margin ** 2))
        radius = radius + confidence * np.sqrt(np.maximum(position_spread, 0.0))
    return np.zeros_like(encounter.cov), radius, True


def _monte_carlo_probabilities(encounter, layout, directions, speeds, config, rng):
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
    velocity = 2.0 * config.max_speed * speeds[..., None] * directions[:, None, :]
    probabilities = []
    for index in range(encounter.origin.shape[0]):
        eigenvalues, eigenvectors = np.linalg.eigh(encounter.cov[index])
        root = eigenvectors * np.sqrt(np.maximum(eigenvalues, 0.0))
        z = encounter.origin[index] + rng.standard_normal((config.mc_samples, 4)) @ root.T
        rel_x, rel_y = z[:, 0], z[:, 1]
        u_x = z[:, 2] + velocity[..., 0, None]
        u_y = z[:, 3] + velocity[..., 1, None]
        radius_sq = encounter.combined_radius[index] ** 2
        speed_sq = u_x * u_x + u_y * u_y
        event = (rel_x * u_y - rel_y * u_x) ** 2 - radius_sq * speed_sq >= 0.0
        closing = rel_x * u_x + rel_y * u_y
        if layout.receding_enabled[index]:
            event |= closing >= 0.0
        if layout.has_horizon:
            tau = config.time_horizon
            event |= ((-closing - tau * speed_sq >= 0.0)
                      & ((rel_x + tau * u_x) ** 2 + (rel_y + tau * u_y) ** 2 >= radius_sq))
        probabilities.append(np.mean(event, axis=-1))
    return np.array(probabilities)


def _validated_inputs(ego, neighbours, v_pref, config, previous):
    if not isinstance(ego, AgentBelief):
        raise ValueError(f'ego must be an AgentBelief, got {ego!r}')
    neighbours = list(neighbours)
    for index, neighbour in enumerate(neighbours):
        if not isinstance(neighbour, AgentBelief):
            raise ValueError(f'neighbours[{index}] must be an AgentBelief, got {neighbour!r}')
    if not isinstance(config, PlannerConfig):
        raise ValueError(f'config must be a PlannerConfig, got {config!r}')
    if previous is not None:
        previous = as_finite_array(previous, (2,), 'previous')
    return neighbours, as_finite_array(v_pref, (2,), 'v_pref'), previous


def _distances(points, point):
    """Euclidean distances of POINTS (..., 2) from POINT (2,), shape (...)."""
    offset = points - point
    # sqrt of a sum, not np.linalg.norm: a fraction of the cost on the small arrays of a plan.
    return np.sqrt(offset[..., 0] * offset[..., 0] + offset[..., 1] * offset[..., 1])


def _choice_costs(velocities, v_pref, previous, config):
    """
    Cost of commanded velocities, shape (..., 2) -> (...): smaller is better.

    ``|v - v_pref|`` (prvo-math.md section 7), plus ``inertia |v - previous|`` when a previous
    command is given and ``passing_bias max(0, left(v))`` with ``left`` the component of ``v``
    to the left of ``v_pref``'s direction. Both extra terms are convex in ``v`` and only rank
    velocities; which ones are acceptable is decided by the constraints alone.
    """
    costs = _distances(velocities, v_pref)
    if previous is not None and config.inertia > 0.0:
        costs += config.inertia * _distances(velocities, previous)
    norm = math.hypot(v_pref[0], v_pref[1])
    if config.passing_bias > 0.0 and norm > 1e-9:
        left = (v_pref[0] * velocities[..., 1] - v_pref[1] * velocities[..., 0]) / norm
        costs += config.passing_bias * np.maximum(left, 0.0)
    return costs


def _best_speeds(directions, lower, upper, preferred, v_pref, previous, config):
    """
    Best ``t`` in ``[lower, upper]`` on each ray ``t v_max e``, shape (G,).

    Under the plain cost it is the preferred ``t`` projected onto the interval. The extra terms
    of :func:`_choice_costs` keep the cost convex along the ray, so its minimum lies within a
    cell of the best point of a grid; zooming a grid onto those two cells a few times finds it
    (the interval ends and the plain optimum are candidates too: a flat or kinked minimum).
    Only intervals that can hold the overall optimum are searched; the others keep the
    projected ``t``, whose cost cannot be the smallest.
    """
    projected = np.clip(preferred, lower, upper)
    if not ((previous is not None and config.inertia > 0.0) or config.passing_bias > 0.0):
        return projected
    # The plain term alone, smallest at the projected t, bounds an interval's cost from below
    # (the extra terms are >= 0); the full cost at a projected t bounds the optimum from above.
    at_projected = config.max_speed * projected[:, None] * directions
    plain = _distances(at_projected, v_pref)
    searched = (plain <= _choice_costs(at_projected, v_pref, previous, config).min()).nonzero()[0]
    best = projected.copy()
    best[searched] = _zoomed_speeds(directions[searched], lower[searched], upper[searched],
                                    projected[searched], v_pref, previous, config)
    return best


def _zoomed_speeds(directions, lower, upper, projected, v_pref, previous, config):
    """Minimise :func:`_choice_costs` on each ray's interval by a zoomed grid, shape (G,)."""
    velocity_directions = config.max_speed * directions[:, None, :]
    low, high = lower, upper
    for _ in range(_ZOOM_LEVELS):
        grid = low[:, None] + (high - low)[:, None] * _ZOOM_GRID
        best = np.argmin(_choice_costs(grid[..., None] * velocity_directions, v_pref, previous,
                                       config), axis=1)
        rows = np.arange(grid.shape[0])
        # The minimum of a convex function lies within one cell of the best grid point.
        low = grid[rows, np.maximum(best - 1, 0)]
        high = grid[rows, np.minimum(best + 1, _ZOOM_GRID.size - 1)]
    options = np.stack([0.5 * (low + high), projected, lower, upper], axis=1)
    option_costs = _choice_costs(options[..., None] * velocity_directions, v_pref, previous,
                                 config)
    return options[np.arange(options.shape[0]), np.argmin(option_costs, axis=1)]


def _clip_speed(velocity, max_speed):
    speed = math.hypot(velocity[0], velocity[1])
    return velocity * (max_speed / speed) if speed > max_speed else np.array(velocity)


def plan_velocity(ego, neighbours, v_pref, config, previous=None):
    """
    Choose the commanded velocity closest to ``v_pref`` that meets the chance constraints.

    "Closest" is the cost of :func:`_choice_costs`: the distance to ``v_pref`` unless
    ``config.inertia`` or ``config.passing_bias`` add their terms.

    Parameters
    ----------
    ego : AgentBelief
        Belief over the planning robot (its mean velocity is a candidate direction).
    neighbours : sequence of AgentBelief
        Beliefs over the other robots.
    v_pref : array_like
        Preferred velocity, shape (2,).
    config : PlannerConfig
        Planner parameters.
    previous : array_like or None
        The previous command, shape (2,), for ``config.inertia``; None for none.

    Returns
    -------
    PlanResult
        The velocity (never NaN, ``|v| <= max_speed``) and its diagnostics.

    Raises
    ------
    ValueError
        On invalid inputs.

    """
    neighbours, v_pref, previous = _validated_inputs(ego, neighbours, v_pref, config, previous)
    encounter = build_encounter(ego, neighbours, config)
    count = encounter.origin.shape[0]
    directions = candidate_directions(ego, v_pref, config)
    if count == 0:
        return PlanResult(velocity=_clip_speed(v_pref, config.max_speed), feasible=True,
                          achieved_k=math.inf, eta_bound=1.0, num_constraints=0,
                          candidates_feasible=directions.shape[0])
    layout = condition_layout(encounter, config)
    preferred = directions @ v_pref / config.max_speed
    if config.model == 'mc':
        speeds, grid_costs = _speed_grid(directions, preferred, v_pref, previous, config)
        probabilities = _monte_carlo_probabilities(encounter, layout, directions, speeds,
                                                   config, np.random.default_rng(config.seed))
        feasible_points = np.all(probabilities >= encounter.eta, axis=0)
        candidates_feasible = int(np.count_nonzero(np.any(feasible_points, axis=1)))
        if candidates_feasible:
            flat = int(np.argmin(np.where(feasible_points, grid_costs, np.inf)))
        else:
            flat = _best_ranked(np.min(probabilities, axis=0), grid_costs)
        direction_index, speed_index = np.unravel_index(flat, speeds.shape)
        velocity = config.max_speed * speeds[direction_index, speed_index] * \
            directions[direction_index]
    else:
        cov, radius, deterministic = _model_moments(encounter, config)
        means, variances = ray_polynomials(encounter.origin, cov, radius, directions,
                                           config.max_speed, config.time_horizon,
                                           layout.has_receding)
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, config.method, deterministic, preferred)
        candidates_feasible = int(np.count_nonzero(
            np.bincount(gap_direction, minlength=directions.shape[0])))
        if candidates_feasible:
            # The best speed on a ray within one interval (the preferred one, projected, under
            # the plain cost).
            inset = np.minimum(_INTERIOR, 0.5 * (upper - lower))
            best_t = _best_speeds(directions[gap_direction], lower + inset, upper - inset,
                                  preferred[gap_direction], v_pref, previous, config)
            candidates = config.max_speed * best_t[:, None] * directions[gap_direction]
            best = int(np.argmin(_choice_costs(candidates, v_pref, previous, config)))
            direction_index, chosen_t = gap_direction[best], best_t[best]
        else:
            speeds, grid_costs = _speed_grid(directions, preferred, v_pref, previous, config)
            score = _grid_scores(means, variances, speeds, layout, deterministic)
            direction_index, speed_index = np.unravel_index(_best_ranked(score, grid_costs),
                                                            speeds.shape)
            chosen_t = speeds[direction_index, speed_index]
        velocity = config.max_speed * chosen_t * directions[direction_index]
    if config.model == 'prvo':
        # The planning moments are the beliefs' own: evaluate the ray polynomials.
        at_velocity = [poly_eval(polynomial[:, direction_index], chosen_t)
                       for polynomial in (means, variances)]
    else:
        at_velocity = [moment[:, 0] for moment in condition_moments(
            encounter.origin, encounter.cov, encounter.combined_radius, velocity[None, :],
            config.time_horizon, layout.has_receding)]
    achieved = float(achieved_margins(*at_velocity, layout, layout.receding_enabled).min())
    velocity = _clip_speed(velocity, config.max_speed)
    return PlanResult(velocity=velocity,
                      feasible=bool(candidates_feasible) and not encounter.overlapping.any(),
                      achieved_k=achieved, eta_bound=_cantelli(achieved),
                      num_constraints=count, candidates_feasible=candidates_feasible)


def _speed_grid(directions, preferred, v_pref, previous, config):
    """
    Candidate speeds for sampling-based choices and their choice costs.

    Returns
    -------
    speeds : numpy.ndarray
        ``t`` per direction, shape (M, T): the preferred one (clipped), then a fixed grid.
    costs : numpy.ndarray
        :func:`_choice_costs` of ``t v_max e``, shape (M, T).

    """
    speeds = np.concatenate([np.clip(preferred, 0.0, 1.0)[:, None],
                             np.broadcast_to(_SPEED_GRID, (directions.shape[0],
                                                           _SPEED_GRID.size))], axis=1)
    costs = _choice_costs(config.max_speed * speeds[..., None] * directions[:, None, :], v_pref,
                          previous, config)
    return speeds, costs


def _grid_scores(means, variances, speeds, layout, deterministic):
    """
    Ranked achieved ``k`` at candidate speeds, minimised over neighbours.

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition polynomials, shapes (N, M, C, 3) and (N, M, C, 5).
    speeds : numpy.ndarray
        ``t`` per direction, shape (M, T).
    layout : ConditionLayout
        Column meaning.
    deterministic : bool
        All variances are zero: rank by the normalised margin (``achieved_margins``' ``rank``).

    Returns
    -------
    numpy.ndarray
        Shape (M, T).

    """
    count, directions, conditions = means.shape[:3]
    # Speed 0 is each direction's own (Horner's rule, per direction); the others are the same
    # grid on every direction: one product with the coefficient-major rows of every
    # (neighbour, direction, condition). Grid values are laid out (T, N, M, C).
    own = np.tile(np.repeat(speeds[:, 0], conditions), count)
    grid = []
    for polynomial in (means, variances):
        rows = polynomial.transpose(3, 0, 1, 2).reshape(polynomial.shape[-1], -1)
        values = np.empty((speeds.shape[1], rows.shape[1]))
        values[1:] = _SPEED_GRID_POWERS[:, :rows.shape[0]] @ rows
        values[0] = _horner_coefficient_major(rows, own)
        grid.append(values.reshape(speeds.shape[1], count, directions, conditions))
    scores = np.min(achieved_margins(grid[0], grid[1], layout, layout.receding_enabled[:, None],
                                     rank=deterministic, scratch=True), axis=1)
    return scores.T


def _cantelli(margin):
    """Cantelli bound ``k^2 / (1 + k^2)`` of ``max(margin, 0)`` for a Python float."""
    if margin <= 0.0:
        return 0.0
    return 1.0 if math.isinf(margin) else margin * margin / (1.0 + margin * margin)


def _best_ranked(score, costs):
    """Flat index of the largest score, ties (within rounding) broken by the smallest cost."""
    best = np.max(score)
    if np.isfinite(best):
        ties = score >= best - 1e-9 * max(1.0, abs(best))
    else:
        ties = score == best
    return int(np.argmin(np.where(ties, costs, np.inf)))
