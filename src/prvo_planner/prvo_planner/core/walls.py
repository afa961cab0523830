"""
Chance constraints against static obstacles: wall segments and discs (docs/method.md, walls).

Against a static obstacle only the ego's uncertainty remains: its position ``p ~ N(mu, S_p)``
and its execution error ``eps ~ N(0, S_a)``. Over the obstacle horizon ``tau`` the ego moves
along ``p(t) = p + t (v + eps)`` for the command ``v``, and touches a wall ``[a, b]`` of
half-width ``w`` exactly when its centre enters the capsule of radius
``R = R_i + w + margin`` around the segment.

A linear condition ``y(t) = n.p(t) - c >= 0`` at ``t = 0`` and ``t = tau`` keeps the straight
path out of the half-plane ``n.x < c`` for the whole horizon. Both values are Gaussian:
``y(0) ~ N(m0, s0^2)`` with ``m0 = n.mu - c``, ``s0^2 = n' S_p n``, and
``y(tau) ~ N(m0 + tau n.v, s0^2 + tau^2 n' S_a n)``. With ``delta0 = Phi(-m0 / s0)`` and a risk
``delta > delta0``, the union bound gives ``P(y(0) >= 0 and y(tau) >= 0) >= 1 - delta`` when
``m0 + tau n.v >= z sqrt(s0^2 + tau^2 n' S_a n)``, ``z = Phi^-1(1 - delta + delta0)``: on a
ray ``v = t v_max e`` one linear inequality in ``t``.

Per wall (``delta = 1 - eta``) a velocity is accepted if either

* the support line holds: ``n`` the unit vector from the segment's closest point to ``mu``,
  ``c = max(n.a, n.b) + R``, risk ``delta``; or
* the decomposition holds: the capsule lies in the two end discs and the rectangle
  ``0 < xi < L, |zeta| < R`` (wall coordinates ``xi`` along ``b - a`` from ``a``, ``zeta``
  across); the rectangle is avoided when one of ``zeta >= R``, ``zeta <= -R``, ``xi <= 0``,
  ``xi >= L`` holds at both ends of the horizon, each a linear condition as above; the end
  discs are static neighbours (share of the avoidance 0, no velocity, no covariance of their
  own), planned with the neighbours' conditions over the obstacle horizon.

The risk of the decomposition is split by a rule fixed in advance: an end disc the ego cannot
reach except with probability at most ``delta / 100`` (the a-priori bound below) is charged
that bound; the rest of ``delta`` is split equally between the rectangle and the end discs
within reach. The a-priori bound: every point of the path is within
``|p - mu| + tau (v_max + |eps|)`` of ``mu``, and a 2D Gaussian of largest variance
``lambda`` exceeds a norm ``r`` with probability at most ``exp(-r^2 / (2 lambda))``; splitting
``r = |mu - centre| - R - tau v_max`` in proportion to the two deviations gives
``2 exp(-r^2 / (2 (sigma_p + tau sigma_a)^2))``.

Close to a wall (the mean within the capsule, or ``delta0 >= delta`` on the support line)
nothing certifies the horizon: only velocities that move away from the wall with probability
``eta``, ``P(n.(v + eps) >= 0) >= eta``, are accepted.

On every ray each wall accepts ``[0, upper] U [lower, 1]`` in ``t`` (a union of half-lines is
one), so it rejects at most one open interval ``(upper, lower)``; the rays' intervals are
intersected with the neighbours' feasible intervals in one sorted sweep.
"""

from dataclasses import dataclass
import math

import numpy as np
from scipy.special import ndtr, ndtri

from .probability import confidence_ellipse_scale

# An end disc whose a-priori bound is at most this share of a wall's risk is out of reach.
REACH_SHARE = 0.01
# Linear conditions per wall: the support line, then the rectangle's four sides.
_CONDITIONS = 5


@dataclass(frozen=True)
class WallModel:
    """
    One plan's static obstacles as linear conditions and static neighbours.

    Attributes
    ----------
    mean_position : numpy.ndarray
        The ego's mean position ``mu``, shape (2,).
    segments : numpy.ndarray
        Shape (N, 2, 2), the walls.
    radius : numpy.ndarray
        Capsule radius ``R`` per wall, shape (N,).
    distance : numpy.ndarray
        Distance of ``mu`` from each segment, shape (N,).
    normals : numpy.ndarray
        Shape (N, 5, 2): the support line's ``n``, then the rectangle's four sides'.
    mean0, std0, std_tau : numpy.ndarray
        ``m0``, ``s0`` and ``sqrt(s0^2 + tau^2 n' S_a n)`` per condition, shape (N, 5).
    risks : numpy.ndarray
        The risk each condition is planned with, shape (N, 5).
    close : numpy.ndarray
        Per wall, whether only moving away is accepted, shape (N,).
    away_threshold : numpy.ndarray
        ``Phi^-1(eta) sqrt(n' S_a n)`` of the support line's ``n``, shape (N,).
    end_bounds : numpy.ndarray
        A-priori bound of each wall end, shape (N, 2); ``nan`` for an end within reach.
    end_disc : numpy.ndarray
        Index into the static neighbours of each end within reach, else -1, shape (N, 2).
    disc_centres, disc_radii, disc_etas : numpy.ndarray
        The static neighbours: end discs within reach (radius the wall's half-width), then the
        disc obstacles within reach; shapes (D, 2), (D,), (D,) (``eta`` each is planned with).
    disc_bounds : numpy.ndarray
        A-priori bound of every disc obstacle (``nan`` within reach: a neighbour), shape (Q,).
    disc_obstacle : numpy.ndarray
        Index into the static neighbours of every disc obstacle within reach, else -1, (Q,).
    obstacle_centres, obstacle_radius : numpy.ndarray
        Every disc obstacle's centre (Q, 2) and ``R_i + r + margin`` (Q,).
    horizon, max_speed, eta : float
        ``tau``, ``v_max`` and the probability per obstacle.
    deterministic : bool
        No uncertainty is planned with (the means alone decide).

    """

    mean_position: np.ndarray
    segments: np.ndarray
    radius: np.ndarray
    distance: np.ndarray
    normals: np.ndarray
    mean0: np.ndarray
    std0: np.ndarray
    std_tau: np.ndarray
    risks: np.ndarray
    close: np.ndarray
    away_threshold: np.ndarray
    end_bounds: np.ndarray
    end_disc: np.ndarray
    disc_centres: np.ndarray
    disc_radii: np.ndarray
    disc_etas: np.ndarray
    disc_bounds: np.ndarray
    disc_obstacle: np.ndarray
    obstacle_centres: np.ndarray
    obstacle_radius: np.ndarray
    horizon: float
    max_speed: float
    eta: float
    deterministic: bool

    @property
    def clearance(self):
        """Distance of ``mu`` from the nearest capsule's surface [m] (``inf``: none)."""
        walls = self.distance - self.radius
        discs = (np.hypot(*(self.obstacle_centres - self.mean_position).T)
                 - self.obstacle_radius)
        return float(np.min(np.concatenate([walls, discs]), initial=math.inf))


def closest_points(point, segments):
    """
    Closest point of each segment to POINT, and the distance.

    Parameters
    ----------
    point : numpy.ndarray
        Shape (2,).
    segments : numpy.ndarray
        Shape (N, 2, 2).

    Returns
    -------
    closest : numpy.ndarray
        Shape (N, 2).
    distance : numpy.ndarray
        Shape (N,).

    """
    start, along = segments[:, 0], segments[:, 1] - segments[:, 0]
    fraction = np.clip(np.sum((point - start) * along, axis=1)
                       / np.sum(along * along, axis=1), 0.0, 1.0)
    closest = start + fraction[:, None] * along
    offset = point - closest
    return closest, np.hypot(offset[:, 0], offset[:, 1])


def _below_zero(mean, std):
    """``P(N(mean, std^2) < 0)``, elementwise; a known value (std 0) gives 0 or 1."""
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = np.where(std > 0.0, mean / np.where(std > 0.0, std, 1.0),
                         np.where(mean >= 0.0, np.inf, -np.inf))
    return ndtr(-ratio)


def _quadratic_form(normals, cov):
    """``n' S n`` for normals (..., 2)."""
    return np.einsum('...i,ij,...j->...', normals, cov, normals)


def _reach_bounds(centres, radius, mean, spread, horizon, max_speed):
    """A-priori bound on the path entering discs (centres (K, 2), radius (K,)) within tau."""
    gap = np.hypot(*(centres - mean).T) - radius - horizon * max_speed
    with np.errstate(divide='ignore', invalid='ignore'):
        exponent = np.where(spread > 0.0, -0.5 * (gap / max(spread, 1e-300)) ** 2, -np.inf)
    return np.where(gap > 0.0, np.minimum(2.0 * np.exp(exponent), 1.0), 1.0)


def wall_model(obstacles, ego, config):
    """
    Build one plan's conditions against OBSTACLES (a ``StaticObstacles``).

    Parameters
    ----------
    obstacles : StaticObstacles
        The walls and discs, world frame.
    ego : AgentBelief
        The planning robot (its position mean and covariance, its planning radius).
    config : PlannerConfig
        ``obstacle_horizon``, ``max_speed``, ``actuation_cov``, ``safety_margin``, ``model``
        and the probability ``effective_eta`` per obstacle.

    Returns
    -------
    WallModel

    """
    mean = ego.position
    eta = config.effective_eta
    delta = 1.0 - eta
    horizon = config.obstacle_horizon
    position_cov, actuation_cov = ego.covariance[:2, :2], config.actuation_cov
    growth = 0.0
    if config.model in ('rvo', 'inflate'):
        if config.model == 'inflate':
            growth = confidence_ellipse_scale(config.effective_k) * math.sqrt(
                max(float(np.linalg.eigvalsh(position_cov)[-1]), 0.0))
        position_cov, actuation_cov = np.zeros((2, 2)), np.zeros((2, 2))
    deterministic = not (position_cov.any() or actuation_cov.any())
    spread = (math.sqrt(max(float(np.linalg.eigvalsh(position_cov)[-1]), 0.0))
              + horizon * math.sqrt(max(float(np.linalg.eigvalsh(actuation_cov)[-1]), 0.0)))
    segments = obstacles.segments
    count = len(segments)
    radius = ego.radius + obstacles.half_widths + config.safety_margin + growth
    closest, distance = closest_points(mean, segments)
    along = segments[:, 1] - segments[:, 0]
    length = np.hypot(along[:, 0], along[:, 1])
    unit = along / length[:, None]
    across = np.stack([-unit[:, 1], unit[:, 0]], axis=1)
    offset = mean - closest
    with np.errstate(divide='ignore', invalid='ignore'):
        support = np.where((distance > 0.0)[:, None], offset / distance[:, None], across)
    start_side = np.sum(support * segments[:, 0], axis=1)
    end_side = np.sum(support * segments[:, 1], axis=1)
    normals = np.stack([support, across, -across, -unit, unit], axis=1)
    offsets = np.stack([
        np.maximum(start_side, end_side) + radius,
        np.sum(across * segments[:, 0], axis=1) + radius,
        -np.sum(across * segments[:, 0], axis=1) + radius,
        -np.sum(unit * segments[:, 0], axis=1),
        np.sum(unit * segments[:, 1], axis=1)], axis=1)
    mean0 = normals @ mean - offsets
    var0 = _quadratic_form(normals, position_cov)
    std0 = np.sqrt(np.maximum(var0, 0.0))
    std_tau = np.sqrt(np.maximum(var0 + horizon ** 2 * _quadratic_form(normals,
                                                                     actuation_cov), 0.0))
    start_risk = _below_zero(mean0[:, 0], std0[:, 0])
    close = (distance <= radius) | (start_risk >= delta)
    # The decomposition's risk split: ends out of reach keep their a-priori bound.
    ends = segments.reshape(-1, 2)
    end_bounds = _reach_bounds(ends, np.repeat(radius, 2), mean, spread, horizon,
                               config.max_speed).reshape(count, 2)
    in_reach = (end_bounds > REACH_SHARE * delta) & ~close[:, None]
    end_bounds = np.where(in_reach, np.nan, end_bounds)
    share = (delta - np.nansum(end_bounds, axis=1)) / (1.0 + in_reach.sum(axis=1))
    risks = np.concatenate([np.full((count, 1), delta), np.repeat(share[:, None], 4, axis=1)],
                           axis=1)
    # End discs within reach, shared ends once (the strictest probability).
    end_keys = np.concatenate([ends, np.repeat(obstacles.half_widths, 2)[:, None]],
                              axis=1)[in_reach.ravel()]
    end_etas = np.repeat(1.0 - share, 2)[in_reach.ravel()]
    unique, inverse = np.unique(end_keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    unique_etas = np.full(len(unique), -np.inf)
    np.maximum.at(unique_etas, inverse, end_etas)
    end_disc = np.full(2 * count, -1)
    end_disc[in_reach.ravel()] = inverse
    obstacle_radius = ego.radius + obstacles.disc_radii + config.safety_margin + growth
    disc_bounds = _reach_bounds(obstacles.disc_centres, obstacle_radius, mean, spread, horizon,
                                config.max_speed)
    disc_in_reach = disc_bounds > REACH_SHARE * delta
    disc_obstacle = np.full(len(disc_bounds), -1)
    disc_obstacle[disc_in_reach] = len(unique) + np.arange(int(disc_in_reach.sum()))
    support_away = _quadratic_form(support, actuation_cov)
    return WallModel(
        mean_position=mean, segments=segments, radius=radius, distance=distance, normals=normals, mean0=mean0,
        std0=std0, std_tau=std_tau, risks=risks, close=close,
        away_threshold=ndtri(eta) * np.sqrt(np.maximum(support_away, 0.0)),
        end_bounds=end_bounds, end_disc=end_disc.reshape(count, 2),
        disc_centres=np.concatenate([unique[:, :2], obstacles.disc_centres[disc_in_reach]]),
        disc_radii=np.concatenate([unique[:, 2], obstacles.disc_radii[disc_in_reach]]),
        disc_etas=np.concatenate([unique_etas, np.full(int(disc_in_reach.sum()), eta)]),
        disc_bounds=np.where(disc_in_reach, np.nan, disc_bounds), disc_obstacle=disc_obstacle,
        obstacle_centres=obstacles.disc_centres, obstacle_radius=obstacle_radius,
        horizon=horizon, max_speed=config.max_speed, eta=eta, deterministic=deterministic)


def static_neighbours(model, ego, config):
    """
    The static neighbours of MODEL as the neighbours' relative Gaussians (``Encounter`` rows).

    A static disc of centre ``c`` and radius ``r`` has no velocity and no covariance of its own
    and takes no share of the avoidance (``rho = 1``): ``r = p_i - c``, ``w = v_x``, so the
    mean at zero command is ``(mu - c, 0)``, the covariance ``diag(S_p, S_a)``, the factor of
    the command 1 and the radius ``R_i + r + margin``.

    Returns
    -------
    origin, cov, lead, combined_radius, overlapping : numpy.ndarray
        Shapes (D, 4), (D, 4, 4), (D,), (D,), (D,).

    """
    count = len(model.disc_radii)
    origin = np.zeros((count, 4))
    origin[:, :2] = ego.position - model.disc_centres
    cov = np.zeros((count, 4, 4))
    cov[:, :2, :2] = ego.covariance[:2, :2]
    cov[:, 2:, 2:] = config.actuation_cov
    combined_radius = ego.radius + model.disc_radii + config.safety_margin
    distance = np.hypot(origin[:, 0], origin[:, 1])
    return origin, cov, np.ones(count), combined_radius, distance < combined_radius


def rejected_intervals(model, directions):
    """
    The ``t`` each wall rejects on each ray: the open interval ``(upper, lower)``.

    Parameters
    ----------
    model : WallModel
        The walls.
    directions : numpy.ndarray
        Unit ray directions, shape (M, 2).

    Returns
    -------
    upper, lower : numpy.ndarray
        Shape (N, M): the wall accepts ``[0, upper] U [lower, 1]`` (``upper`` may be below 0,
        ``lower`` above 1).

    """
    # a t >= b per (wall, condition, ray).
    slope = model.horizon * model.max_speed * (model.normals @ directions.T)
    start_risk = _below_zero(model.mean0, model.std0)
    usable = start_risk < model.risks
    with np.errstate(invalid='ignore'):
        quantile = ndtri(np.where(usable, 1.0 - model.risks + start_risk, 0.5))
    bound = np.where(usable, quantile * model.std_tau - model.mean0, np.inf)[..., None]
    # Moving away, for walls too close to certify: v_max (n.e) t >= z_eta sqrt(n' S_a n).
    away_slope = model.max_speed * (model.normals[:, 0] @ directions.T)
    slope[:, 0] = np.where(model.close[:, None], away_slope, slope[:, 0])
    bound[:, 0] = np.where(model.close, model.away_threshold, bound[:, 0, 0])[:, None]
    bound[:, 1:] = np.where(model.close[:, None, None], np.inf, bound[:, 1:])
    with np.errstate(divide='ignore', invalid='ignore'):
        cut = bound / slope
    upper = np.where(slope < 0.0, cut, np.where((slope == 0.0) & (bound <= 0.0), np.inf,
                                                -np.inf))
    lower = np.where(slope > 0.0, cut, np.inf)
    return upper.max(axis=1), lower.min(axis=1)


def cut_by_walls(gap_ray, lower, upper, wall_ray, wall_upper, wall_lower):
    """
    Feasible intervals minus the walls' rejected open intervals, in one sorted sweep.

    The feasible intervals of a ray are disjoint; a point is kept when it lies in one of them
    and in no rejected interval: with weights 1 for feasible and 2 for rejected intervals, where
    the running sum is 1.

    Parameters
    ----------
    gap_ray, lower, upper : numpy.ndarray
        Feasible intervals (ray, lower, upper), shape (G,).
    wall_ray, wall_upper, wall_lower : numpy.ndarray
        Rejected intervals (ray, start, end), shape (W,).

    Returns
    -------
    ray, lower, upper : numpy.ndarray
        The remaining intervals, ``lower < upper``, sorted by ray and position.

    """
    keep = (wall_upper < wall_lower) & (wall_lower > 0.0) & (wall_upper < 1.0)
    wall_ray, wall_upper, wall_lower = wall_ray[keep], wall_upper[keep], wall_lower[keep]
    rays = np.concatenate([gap_ray, gap_ray, wall_ray, wall_ray])
    points = np.concatenate([lower, upper, np.maximum(wall_upper, -1.0),
                             np.minimum(wall_lower, 2.0)])
    steps = np.concatenate([np.ones(gap_ray.size), -np.ones(gap_ray.size),
                            np.full(wall_ray.size, 2.0), np.full(wall_ray.size, -2.0)])
    order = np.lexsort((steps, points, rays))
    rays, points, level = rays[order], points[order], np.cumsum(steps[order])
    kept = np.flatnonzero(level[:-1] == 1.0)
    kept = kept[points[kept] < points[kept + 1]]
    return rays[kept], points[kept], points[kept + 1]


def _segment_distances(points, starts, ends):
    """Distance of points (K, 1, 2) from segments (starts, ends) (.., N, 2): shape (K, N)."""
    along = ends - starts
    length_sq = np.sum(along * along, axis=-1)
    with np.errstate(divide='ignore', invalid='ignore'):
        fraction = np.where(length_sq > 0.0,
                            np.sum((points - starts) * along, axis=-1) / length_sq, 0.0)
    closest = starts + np.clip(fraction, 0.0, 1.0)[..., None] * along
    offset = points - closest
    return np.hypot(offset[..., 0], offset[..., 1])


def _cross(first, second):
    return first[..., 0] * second[..., 1] - first[..., 1] * second[..., 0]


def wall_intrusion(model, velocities, period):
    """
    How far each command moves into a wall or disc obstacle within one period, shape (K,).

    Per obstacle ``min(d0, R) - d1`` (0 if nowhere), with ``d0`` the distance of ``mu`` and
    ``d1`` the smallest distance of the path ``mu + t v``, ``t in [0, period]``, from the
    segment (or disc centre): the overlap the command creates, or adds to an existing one.
    The largest over the obstacles; 0 for ``v = 0``.

    Parameters
    ----------
    model : WallModel
        The obstacles.
    velocities : numpy.ndarray
        Candidate commands, shape (K, 2).
    period : float
        How long a command stays in force, seconds.

    """
    start = model.mean_position
    finish = start + period * velocities
    path_start = np.broadcast_to(start, finish.shape)[:, None, :]
    path_end = finish[:, None, :]
    wall_a, wall_b = model.segments[None, :, 0], model.segments[None, :, 1]
    distance = np.minimum.reduce([
        _segment_distances(path_start, wall_a, wall_b),
        _segment_distances(path_end, wall_a, wall_b),
        _segment_distances(wall_a, path_start, path_end),
        _segment_distances(wall_b, path_start, path_end)])
    wall_along, path_along = wall_b - wall_a, path_end - path_start
    crossing = ((_cross(wall_along, path_start - wall_a) * _cross(wall_along, path_end - wall_a)
                 < 0.0)
                & (_cross(path_along, wall_a - path_start)
                   * _cross(path_along, wall_b - path_start) < 0.0))
    distance = np.where(crossing, 0.0, distance)
    walls = np.maximum(np.minimum(model.distance, model.radius) - distance, 0.0)
    centres = model.obstacle_centres[None, :, :]
    disc_start = np.hypot(*(model.obstacle_centres - start).T)
    discs = np.maximum(np.minimum(disc_start, model.obstacle_radius)
                       - _segment_distances(centres, path_start, path_end), 0.0)
    return np.max(np.concatenate([walls, discs], axis=1), axis=1, initial=0.0)


def obstacle_probability(model, velocity, disc_bounds):
    """
    The probability certified against the obstacles at VELOCITY: the smallest over them.

    Per wall the larger of the support line's and the decomposition's union bounds,
    ``1 - delta0 - P(y(tau) < 0)`` for the support line and ``1 - (the rectangle's best side)
    - (each end disc's)``, with an end disc's share its static neighbour's bound (DISC_BOUNDS,
    per static neighbour) or its a-priori bound; per disc obstacle its neighbour's or its
    a-priori bound. Clipped to [0, 1]; 1 without obstacles.

    """
    start_risk = _below_zero(model.mean0, model.std0)
    end_risk = _below_zero(model.mean0 + model.horizon * (model.normals @ velocity),
                           model.std_tau)
    failure = np.minimum(start_risk + end_risk, 1.0)
    neighbour_risk = 1.0 - np.append(disc_bounds, 1.0)
    ends = np.where(model.end_disc >= 0, neighbour_risk[model.end_disc],
                    np.where(np.isnan(model.end_bounds), 1.0, model.end_bounds))
    decomposition = failure[:, 1:].min(axis=1, initial=1.0) + ends.sum(axis=1)
    walls = 1.0 - np.minimum(failure[:, 0], decomposition)
    discs = np.where(model.disc_obstacle >= 0, 1.0 - neighbour_risk[model.disc_obstacle],
                     1.0 - model.disc_bounds)
    return float(np.clip(np.min(np.concatenate([walls, discs]), initial=1.0), 0.0, 1.0))
