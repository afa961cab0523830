"""
The PRVO velocity planner and its baselines (prvo-math.md sections 5 to 9).

One call builds, for every (neighbour, candidate direction) pair, the mean and variance
polynomials of every condition in the ray parameter ``t`` (speed ``t v_max``), finds each pair's
accepted speeds in closed form, intersects them per direction by a sorted sweep over the
rejected pieces, and picks the feasible velocity closest to the preferred one. Everything is
vectorised over neighbours and directions.
"""

from dataclasses import dataclass
import math

import numpy as np

from .beliefs import AgentBelief, as_finite_array
from .config import PlannerConfig, PlanResult
from .moments import condition_moments, poly_eval, ray_polynomials
from .probability import eta_from_k
from .ray_solver import polynomial_roots, quadratic_roots, sign_certificates, taylor_quadratics

# Speeds, as fractions of v_max, tried on every direction when no direction is feasible (and by
# the Monte Carlo baseline), besides the preferred speed on the direction.
_SPEED_GRID = np.linspace(0.0, 1.0, 9)
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
    count = int(np.count_nonzero(near))
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
    cov[:, 2:, :2] = np.swapaxes(cross, -1, -2)
    combined_radius = ego.radius + radii[near] + config.safety_margin
    return Encounter(
        origin=np.concatenate([relative_position[near], -ego.velocity - velocities[near]], axis=1),
        cov=cov, combined_radius=combined_radius,
        overlapping=distance[near] < combined_radius, margin=margin,
        # k' = sqrt((1 + eta) / (1 - eta)) with eta = k^2 / (1 + k^2).
        horizon_margin=math.sqrt(1.0 + 2.0 * margin ** 2), eta=eta_from_k(margin))


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
    offset = 0.0
    if config.seed is not None:
        offset = np.random.default_rng(config.seed).uniform(
            0.0, 2.0 * np.pi / config.num_directions)
    headings = offset + 2.0 * np.pi * np.arange(config.num_directions) / config.num_directions
    directions = [np.stack([np.cos(headings), np.sin(headings)], axis=1)]
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
    return ConditionLayout(has_receding=bool(np.any(enabled)),
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


def achieved_margins(means, variances, layout, receding_enabled, rank=False):
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

    Returns
    -------
    numpy.ndarray
        Shape (...).

    """
    variances = np.maximum(variances, 0.0)
    if rank:
        # sqrt of a sum, not np.hypot: the same floor at a fraction of the cost.
        variances = variances + (_RANK_FLOOR * means) ** 2
    sigma = np.sqrt(variances)
    with np.errstate(divide='ignore', invalid='ignore'):
        margins = np.where(sigma > 0.0, means / sigma, np.where(means >= 0.0, np.inf, -np.inf))
    if layout.has_horizon:
        joint = np.minimum(margins[..., -2], margins[..., -1])
        pairwise = np.where(joint >= 1.0, np.sqrt(np.maximum(joint * joint - 1.0, 0.0) / 2.0),
                            joint - 1.0)
        margins = np.concatenate([margins[..., :-2], pairwise[..., None], pairwise[..., None]],
                                 axis=-1)
    return combine_conditions(margins, layout, receding_enabled, np.maximum, np.minimum)


def _coefficient_major(polynomial):
    """View polynomials of shape (N, M, C, L) as (N, L, M, C)."""
    return np.moveaxis(polynomial, -1, 1)


def _squared_minus(means, scaled_variances):
    """
    Return ``mean^2 - scaled_variance`` for coefficient-major polynomials.

    Parameters
    ----------
    means : numpy.ndarray
        Shape (N, 3, M, C).
    scaled_variances : numpy.ndarray
        Shape (N, 5, M, C).

    Returns
    -------
    numpy.ndarray
        Shape (N, 5, M, C).

    """
    constant, linear, quadratic = means[:, 0], means[:, 1], means[:, 2]
    return np.stack([constant * constant, 2.0 * constant * linear,
                     linear * linear + 2.0 * constant * quadratic, 2.0 * linear * quadratic,
                     quadratic * quadratic], axis=1) - scaled_variances


def _certificates(polynomial):
    """Sign certificates of coefficient-major (N, L, M, C) polynomials, each (N, M, C)."""
    count, length, directions, conditions = polynomial.shape
    nonnegative, negative = sign_certificates(polynomial.reshape(count, length, -1))
    return (nonnegative.reshape(count, directions, conditions),
            negative.reshape(count, directions, conditions))


def _pair_status(means, variances, margins, method, deterministic, preferred):
    """
    Certify conditions accepted or rejected on the whole ray; prepare the per-piece tests.

    For the exact method ``mean - k sigma >= 0`` iff ``mean >= 0`` and ``mean^2 - k^2 var >= 0``
    (the quartic). Where the variance is certified ``>= 0`` the mean can change sign inside a
    piece on which the quartic is ``>= 0`` only at a root of the quartic, so there only the
    quartic's roots bound pieces. Roots are needed only for conditions undecided on the ray.

    Returns
    -------
    accept_all, reject_all : numpy.ndarray
        Per condition, shape (N, M, C).
    tests : list of numpy.ndarray
        Coefficient-major polynomials that decide acceptance (all must be ``>= 0``), each
        (N, L, M, C).
    bounding : list of (numpy.ndarray, numpy.ndarray)
        Coefficient-major polynomials (N, L, M, C) whose roots bound the pieces, each with
        whether its sign on [0, 1] is undecided, (N, M, C).

    """
    if deterministic:
        tests = [_coefficient_major(means)]
    elif method == 'taylor':
        tests = [_coefficient_major(
            taylor_quadratics(means, variances, margins, preferred[None, :, None]))]
    else:
        variances = _coefficient_major(variances)
        tests = [_squared_minus(_coefficient_major(means), margins ** 2 * variances),
                 _coefficient_major(means)]
    certificates = [_certificates(test) for test in tests]
    accept, reject = True, False
    for nonnegative, negative in certificates:
        accept, reject = accept & nonnegative, reject | negative
    # Only a condition undecided on the whole ray can split it, and only where its own test is.
    undecided = ~(accept | reject)
    bounding = [(test, undecided & ~(nonnegative | negative))
                for test, (nonnegative, negative) in zip(tests, certificates, strict=True)]
    if len(tests) == 2:
        mean, mean_undecided = bounding[1]
        bounding[1] = (mean, mean_undecided & ~_certificates(variances)[0])
    return accept, reject, tests, bounding


def _relevant_conditions(reject_all, layout, receding_enabled):
    """
    Mark the conditions whose acceptance can change their pair's.

    A disabled ``g`` cannot, nor can ``h1`` (``h2``) when ``h2`` (``h1``) is rejected on the
    whole ray; their roots need not bound pieces.

    Parameters
    ----------
    reject_all : numpy.ndarray
        Per condition, rejected on the whole ray, shape (N, M, C).
    layout : ConditionLayout
        Column meaning.
    receding_enabled : numpy.ndarray
        Whether ``g`` counts, broadcastable to shape (N, M).

    Returns
    -------
    numpy.ndarray
        Booleans, shape (N, M, C).

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
    accept_all, reject_all, tests, bounding = _pair_status(means, variances, margins, method,
                                                           deterministic, preferred)
    enabled = layout.receding_enabled[:, None]
    relevant = _relevant_conditions(reject_all, layout, enabled)
    accept_all = combine_conditions(accept_all, layout, enabled)
    reject_all = ~combine_conditions(~reject_all, layout, enabled)
    open_directions = ~np.any(reject_all, axis=0)
    open_pairs = ~accept_all & open_directions[None, :]
    pair_neighbour, pair_direction = np.nonzero(open_pairs)
    count = pair_neighbour.size
    pair_index = np.zeros(open_pairs.shape, dtype=int)
    pair_index[pair_neighbour, pair_direction] = np.arange(count)
    breakpoints = []
    for polynomial, undecided in bounding:
        # One coefficient-major column per undecided (pair, condition) row.
        neighbour, direction, condition = np.nonzero(undecided & relevant
                                                     & open_pairs[..., None])
        if neighbour.size == 0:
            continue
        columns = np.ascontiguousarray(polynomial[neighbour, :, direction, condition].T)
        roots = (polynomial_roots(columns) if columns.shape[0] == 5 else
                 quadratic_roots(columns[0], columns[1], columns[2]))
        found = np.full((count, margins.size, roots.shape[-1]), np.nan)
        found[pair_index[neighbour, direction], condition] = roots
        breakpoints.append(found)
    breakpoints = np.concatenate(breakpoints or [np.empty((count, margins.size, 0))], axis=-1)
    breakpoints = breakpoints.reshape(count, breakpoints.shape[1] * breakpoints.shape[2])
    inside = (breakpoints > 0.0) & (breakpoints < 1.0)
    inside_count = np.count_nonzero(inside, axis=1)
    bounds = np.sort(np.concatenate([np.zeros((count, 1)), np.where(inside, breakpoints, 1.0),
                                     np.ones((count, 1))], axis=-1), axis=-1)
    # Roots outside (0, 1) became trailing 1.0 padding: keep each pair's own pieces only, flat.
    bounds = bounds[:, :2 + int(np.max(inside_count, initial=0))]
    own_piece = np.arange(bounds.shape[1] - 1) <= inside_count[:, None]
    piece_pair = np.nonzero(own_piece)[0]
    piece_start, piece_end = bounds[:, :-1][own_piece], bounds[:, 1:][own_piece]
    midpoints = (0.5 * (piece_end + piece_start))[:, None]
    accepted = True
    for test in tests:
        # (Q, L, C): each piece's pair's coefficients; Horner's rule over the coefficient axis.
        coefficients = test[pair_neighbour, :, pair_direction][piece_pair]
        value = coefficients[:, -1]
        for power in range(coefficients.shape[1] - 2, -1, -1):
            value = value * midpoints + coefficients[:, power]
        accepted = accepted & (value >= 0.0)
    accepted = combine_conditions(accepted, layout,
                                  layout.receding_enabled[pair_neighbour[piece_pair]])
    # Sweep the rejected pieces of each open direction, shifted by 4 per direction so that one
    # sort handles every direction; sentinels reject t < 0 and t > 1 and end where the next
    # direction's first sentinel starts, so no gap spans two directions.
    rejected = ~accepted
    piece_direction = pair_direction[piece_pair[rejected]]
    sentinel_direction = np.nonzero(open_directions)[0]
    starts = np.concatenate([piece_start[rejected], np.full(sentinel_direction.size, -1.0),
                             np.full(sentinel_direction.size, 1.0)])
    ends = np.concatenate([piece_end[rejected], np.zeros(sentinel_direction.size),
                           np.full(sentinel_direction.size, 3.0)])
    direction = np.concatenate([piece_direction, sentinel_direction, sentinel_direction])
    starts = starts + 4.0 * direction
    order = np.argsort(starts, kind='stable')
    starts, direction = starts[order], direction[order]
    reach = np.maximum.accumulate((ends + 4.0 * np.concatenate(
        [piece_direction, sentinel_direction, sentinel_direction]))[order])
    valid = (starts[1:] > reach[:-1]) & (direction[1:] == direction[:-1])
    direction = direction[1:][valid]
    return direction, reach[:-1][valid] - 4.0 * direction, starts[1:][valid] - 4.0 * direction


def _model_moments(encounter, config):
    """Covariance and radius the model plans with, and whether it is noise-free."""
    if config.model in ('prvo', 'mc'):
        return encounter.cov, encounter.combined_radius, False
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


def _validated_inputs(ego, neighbours, v_pref, config):
    if not isinstance(ego, AgentBelief):
        raise ValueError(f'ego must be an AgentBelief, got {ego!r}')
    neighbours = list(neighbours)
    for index, neighbour in enumerate(neighbours):
        if not isinstance(neighbour, AgentBelief):
            raise ValueError(f'neighbours[{index}] must be an AgentBelief, got {neighbour!r}')
    if not isinstance(config, PlannerConfig):
        raise ValueError(f'config must be a PlannerConfig, got {config!r}')
    return neighbours, as_finite_array(v_pref, (2,), 'v_pref')


def _clip_speed(velocity, max_speed):
    speed = math.hypot(velocity[0], velocity[1])
    return velocity * (max_speed / speed) if speed > max_speed else np.array(velocity)


def plan_velocity(ego, neighbours, v_pref, config):
    """
    Choose the commanded velocity closest to ``v_pref`` that meets the chance constraints.

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

    Returns
    -------
    PlanResult
        The velocity (never NaN, ``|v| <= max_speed``) and its diagnostics.

    Raises
    ------
    ValueError
        On invalid inputs.

    """
    neighbours, v_pref = _validated_inputs(ego, neighbours, v_pref, config)
    encounter = build_encounter(ego, neighbours, config)
    count = encounter.origin.shape[0]
    directions = candidate_directions(ego, v_pref, config)
    if count == 0:
        return PlanResult(velocity=_clip_speed(v_pref, config.max_speed), feasible=True,
                          achieved_k=math.inf, eta_bound=1.0, num_constraints=0,
                          candidates_feasible=directions.shape[0])
    layout = condition_layout(encounter, config)
    preferred = directions @ v_pref / config.max_speed
    # Candidate speeds for sampling-based choices: the preferred one, then a grid.
    speeds = np.concatenate([np.clip(preferred, 0.0, 1.0)[:, None],
                             np.broadcast_to(_SPEED_GRID, (directions.shape[0],
                                                           _SPEED_GRID.size))], axis=1)
    grid_costs = np.linalg.norm(config.max_speed * speeds[..., None] * directions[:, None, :]
                                - v_pref, axis=-1)
    if config.model == 'mc':
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
        candidates_feasible = int(np.unique(gap_direction).size)
        if candidates_feasible:
            # The best speed on a ray within one interval is the preferred one, projected.
            inset = np.minimum(_INTERIOR, 0.5 * (upper - lower))
            best_t = np.clip(preferred[gap_direction], lower + inset, upper - inset)
            candidates = config.max_speed * best_t[:, None] * directions[gap_direction]
            best = int(np.argmin(np.linalg.norm(candidates - v_pref, axis=1)))
            direction_index, chosen_t = gap_direction[best], best_t[best]
        else:
            score = _grid_scores(means, variances, speeds, layout)
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
    achieved = float(np.min(achieved_margins(*at_velocity, layout, layout.receding_enabled)))
    velocity = _clip_speed(velocity, config.max_speed)
    return PlanResult(velocity=velocity,
                      feasible=bool(candidates_feasible) and not np.any(encounter.overlapping),
                      achieved_k=achieved, eta_bound=_cantelli(achieved),
                      num_constraints=count, candidates_feasible=candidates_feasible)


def _grid_scores(means, variances, speeds, layout):
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

    Returns
    -------
    numpy.ndarray
        Shape (M, T).

    """
    count, directions, conditions = means.shape[:3]
    powers = speeds[..., None] ** np.arange(variances.shape[-1])
    # Per direction, speed powers (T, L) times coefficients (L, N C): one small product each.
    grid_means, grid_variances = (
        (powers[..., :polynomial.shape[-1]] @ polynomial.transpose(1, 3, 0, 2).reshape(
            directions, polynomial.shape[-1], -1)).reshape(
                directions, speeds.shape[1], count, conditions)
        for polynomial in (means, variances))
    return np.min(achieved_margins(grid_means, grid_variances, layout,
                                   layout.receding_enabled, rank=True), axis=-1)


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
