"""
Chance constraints against static obstacles: wall segments and discs (docs/method.md, walls).

Against a static obstacle only the ego's uncertainty remains: its position ``p ~ N(mu, S_p)``
and its execution error. The robot re-plans every control period ``T`` and each command is
executed with an error of its own, so over the obstacle horizon ``tau`` the command ``v`` (the
plan: keep it) moves the ego along ``p(t) = p + t v + W(t)``, ``W`` the random walk of
independent steps ``T eps_k``, ``eps_k ~ N(0, S_a)``, linear within each period. (One error held
for the whole horizon, ``p + t (v + eps)``, made the spread across a door ``tau sigma_a`` where
the executed motion has ``sqrt(tau T) sigma_a``, 0.10 m instead of 0.022 m at ``tau`` 2 s and
``sigma_a`` 0.05, and robots stopped at doors they fit through: issue 37.) The ego touches a
wall ``[a, b]`` of half-width ``w`` exactly when its centre enters the capsule of radius
``R = R_i + w + margin`` around the segment (a disc of radius ``r``: the disc of radius
``R_i + r + margin``).

A linear condition ``y(t) = n.p(t) - c >= 0`` for every ``t`` in ``[0, tau]`` keeps the path
out of the half-plane ``n.x < c`` for the whole horizon. ``y(0) ~ N(m0, s0^2)`` with
``m0 = n.mu - c``, ``s0^2 = n' S_p n``; then ``y`` moves with the drift ``n.v`` and, at whole
periods, as a Brownian motion of variance ``T n' S_a n`` per second, linear in between, so
``y >= 0`` on ``[0, tau]`` (rounded up to whole periods) fails with probability at most the
reflection principle's bound (``wall_kernels.crossing_bounds``, compiled). It grows with the
speed towards the line, ``-n.v``: on a ray ``v = t v_max e`` each condition accepts a
half-line of ``t``, its end the largest speed towards the line whose bound is at most the risk
(the reflected term is at most the first, so it lies between the first term's thresholds at
half the risk and at the risk; regula falsi from there, ``wall_kernels.line_speeds``). A
condition whose bound standing still exceeds its risk accepts nothing. Several conditions
certify a piece when any one of them holds (each with the piece's whole risk); their normals
depend on the beliefs and, for a disc's tangent parallel to a ray
(``wall_kernels._parallel_failure``), on the ray's direction.

Per wall (``delta = 1 - eta``) a velocity is accepted if either

* the support line holds: ``n`` the unit vector from the segment's closest point to ``mu``,
  ``c = max(n.a, n.b) + R``, risk ``delta``; or
* the decomposition holds: the capsule lies in the two end discs and the rectangle
  ``0 < xi < L, |zeta| < R`` (wall coordinates ``xi`` along ``b - a`` from ``a``, ``zeta``
  across); the rectangle is avoided when one of ``zeta >= R``, ``zeta <= -R``, ``xi <= 0``,
  ``xi >= L`` holds over the horizon; an end disc (a static obstacle: no velocity,
  no covariance of its own) when one of its tangent half-planes holds, the normals a fan of
  ``FAN`` directions within ``arccos(R / d)`` of the direction from its centre to ``mu`` (``d``
  the distance), which are the tangents that can hold ``mu``, and on each ray the tangent
  parallel to it (``wall_kernels._parallel_failure``), which a straight path through a door
  keeps to.

The risk of the decomposition is split by a rule fixed in advance: an end disc the ego cannot
reach except with probability at most ``REACH_SHARE delta`` (its a-priori bound) is charged
that bound; the rest of ``delta`` is split equally between the rectangle and the end discs
within reach. The a-priori bound of a shape: every point of the path is within
``|p - mu| + tau v_max + max_t |W(t)|`` of ``mu``; a 2D Gaussian of largest variance
``lambda`` exceeds a norm ``r`` with probability at most ``exp(-r^2 / (2 lambda))``, and the
walk's largest excursion exceeds ``r`` less often than one error held over the horizon,
``tau |eps|``, does: Doob's inequality on two axes gives ``4 exp(-r^2 / (4 tau T lambda))``,
below ``exp(-r^2 / (2 tau^2 lambda))`` for ``tau >= 4 T`` wherever the bound decides
(``r >= 4 tau sigma_a``); splitting ``r = dist(mu, shape) - R - tau v_max`` in
proportion to the two deviations gives ``2 exp(-r^2 / (2 (sigma_p + tau sigma_a)^2))``. A
wall or disc out of reach in this sense constrains nothing and is reported with its a-priori
bound. A disc obstacle is certified by its fan of tangents, or the tangent parallel to the
ray, at risk ``delta``.

Close to a shape (the mean within its grown radius, or the support line's bound standing still
at least ``delta``, the fan's middle normal's for a disc) nothing certifies the horizon: only
velocities that move away over the period with probability ``eta``,
``P(n.(v + eps) >= 0) >= eta``, are accepted.

On a ray each condition accepts a half-line of ``t``, so each piece (any of its conditions)
accepts ``[0, upper] U [lower, 1]`` and rejects at most one open interval ``(upper, lower)``.
A wall rejects where the support line and one of its pieces both do: at most three open
intervals per ray. All of them are cut from the neighbours' feasible intervals in one sorted
sweep.
"""

from dataclasses import dataclass
from functools import lru_cache
import math

import numpy as np

from .probability import confidence_ellipse_scale
from .special import ndtri

# An end disc whose a-priori bound is at most this share of a wall's risk is out of reach.
REACH_SHARE = 0.01
# Tangent normals per disc: fan angles (k / FAN_HALF) arccos(R / d), k = -FAN_HALF..FAN_HALF.
FAN_HALF = 2
FAN = 2 * FAN_HALF + 1
# The support line, the rectangle's four sides, each end disc's fan.
PER_WALL = 5 + 2 * FAN
_RECTANGLE = slice(1, 5)
_START_FAN = slice(5, 5 + FAN)
_END_FAN = slice(5 + FAN, 5 + 2 * FAN)


def _largest_std(cov):
    """Square root of the largest eigenvalue of a 2x2 covariance."""
    half_trace = 0.5 * (cov[0, 0] + cov[1, 1])
    return math.sqrt(max(half_trace + math.hypot(0.5 * (cov[0, 0] - cov[1, 1]), cov[0, 1]),
                         0.0))


@dataclass(frozen=True)
class LinearConditions:
    """
    Linear conditions ``y(t) = n.p(t) - c >= 0`` for all ``t`` in ``[0, tau]``, (K, 2) / (K,).

    The executed path is ``p(t) = p + t v + W(t)``: the command's error is drawn afresh every
    control period ``T`` (the robot re-plans, the world executes each command with its own
    error), so ``W`` is a Gaussian random walk of ``N(0, T^2 S_a)`` steps, piecewise linear
    between them. Across ``n`` it is the Brownian motion of variance ``T n' S_a n`` per second
    seen at whole periods, and between them ``y`` is linear: ``crossing_bounds`` over ``tau``
    rounded up to whole periods bounds the failure. It grows with the speed towards the line
    ``-n.v``; each condition accepts ``n.v >= -approach``.

    Attributes
    ----------
    normals : numpy.ndarray
        ``n``, shape (K, 2).
    mean0, std0, walk : numpy.ndarray
        ``m0 = n.mu - c``, ``s0 = sqrt(n' S_p n)`` and ``T n' S_a n``, shape (K,).
    horizon : float
        ``tau`` rounded up to whole control periods.
    still_risk : numpy.ndarray
        The failure bound without a drift towards the line (standing still), shape (K,).
    risks : numpy.ndarray
        The risk each is planned with, shape (K,); 0: not usable.
    approach : numpy.ndarray
        The largest speed towards the line accepted (``-inf``: none, not even standing still),
        shape (K,).

    """

    normals: np.ndarray
    mean0: np.ndarray
    std0: np.ndarray
    walk: np.ndarray
    horizon: float
    still_risk: np.ndarray
    risks: np.ndarray
    approach: np.ndarray


@dataclass(frozen=True)
class WallModel:
    """
    One plan's static obstacles as linear conditions (docs/method.md, walls).

    Walls and discs out of reach keep only their a-priori bounds; the others are *near*.

    Attributes
    ----------
    mean_position : numpy.ndarray
        The ego's mean position ``mu``, shape (2,).
    clearance : float
        Distance of ``mu`` from the nearest grown shape's surface [m] (``inf``: none).
    far_bounds : numpy.ndarray
        A-priori bounds of the walls and discs out of reach, shape (F,).
    segments, radius, distance : numpy.ndarray
        The near walls (n, 2, 2), their grown radius ``R`` (n,) and distance from ``mu`` (n,).
    centres, disc_radius : numpy.ndarray
        The near disc obstacles (q, 2) and their grown radius (q,).
    conditions : LinearConditions
        Per near wall ``5 + 2 FAN`` conditions (the support line, the rectangle's sides, the
        start's and the end's fans: risk 0 for an end out of reach), wall after wall, then per
        near disc its fan of tangents: ``n (5 + 2 FAN) + q FAN`` in all.
    end_bounds : numpy.ndarray
        A-priori bound charged for each end out of reach (0 within reach), shape (n, 2).
    end_in_reach : numpy.ndarray
        Whether each end is within reach, shape (n, 2): an end out of reach may have a bound
        of 0 (underflow, or no noise), so the bound cannot tell.
    close : numpy.ndarray
        Per near wall then near disc, whether only moving away is accepted, shape (n + q,).
    away_normals, away_thresholds : numpy.ndarray
        Per near wall then near disc, the support line's (the fan's middle) normal (n + q, 2) and
        ``Phi^-1(eta) sqrt(n' S_a n)`` (n + q,).
    horizon, max_speed : float
        ``tau`` and ``v_max``.
    position_cov, walk_cov : numpy.ndarray
        ``S_p`` and ``T S_a`` as planned with, shape (2, 2): the parallel tangents' spreads.

    """

    mean_position: np.ndarray
    clearance: float
    far_bounds: np.ndarray
    segments: np.ndarray
    radius: np.ndarray
    distance: np.ndarray
    centres: np.ndarray
    disc_radius: np.ndarray
    conditions: LinearConditions
    end_bounds: np.ndarray
    end_in_reach: np.ndarray
    close: np.ndarray
    away_normals: np.ndarray
    away_thresholds: np.ndarray
    horizon: float
    max_speed: float
    position_cov: np.ndarray
    walk_cov: np.ndarray


@lru_cache(maxsize=64)
def _quantile(eta):
    """``Phi^-1(eta)``, once per configuration's probability."""
    return ndtri(eta)


def _planning_covariances(ego, config):
    """Return the position and execution covariances the model plans with, and R's growth."""
    position_cov = ego.covariance[:2, :2]
    if config.model == 'prvo':
        return position_cov, config.actuation_cov, 0.0
    growth = 0.0
    if config.model == 'inflate':
        growth = confidence_ellipse_scale(config.effective_k) * _largest_std(position_cov)
    return np.zeros((2, 2)), np.zeros((2, 2)), growth


def certifiable_width(ego, config):
    """
    Return the clear width of a passage below which nothing certifies EGO's way through [m].

    Beside a wall moving along it, the best condition is a line parallel to the motion (the support
    line of the wall beside it, or an end's parallel tangent, ``wall_kernels._parallel_failure``)
    at most at the whole risk ``delta``: its margin ``m`` on each side must bring
    ``crossing_bounds(m, s0, T s_a^2, tau, 0)`` down to ``delta``, with ``s0`` and ``s_a`` the
    largest position and execution stds (any direction). The width is ``2 (R + m)``, ``R`` the
    planning radius grown by ``safety_margin`` (and, for ``inflate``, by its confidence ellipse). A
    narrower door cannot be certified and the robot holds in front of it; a wider one can still be
    too narrow where the ends of a short jamb share the risk.
    """
    from .wall_kernels import crossing_bounds
    position_cov, actuation_cov, growth = _planning_covariances(ego, config)
    std0 = _largest_std(position_cov)
    walk = config.control_period * _largest_std(actuation_cov) ** 2
    horizon = config.control_period * math.ceil(config.obstacle_horizon / config.control_period
                                                - 1e-9)
    risk = 1.0 - config.effective_eta

    def fails(margin):
        return crossing_bounds(np.array([margin]), np.array([std0]), np.array([walk]), horizon,
                               np.zeros(1))[0] > risk

    low, high = 0.0, 10.0 * (std0 + math.sqrt(walk * horizon)) + 1e-9
    if not fails(low):
        high = low
    # Bisection: the bound falls as the margin grows; HIGH always holds.
    while high - low > 1e-6:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if fails(middle) else (low, middle)
    return 2.0 * (ego.radius + config.safety_margin + growth + high)


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
        (``rvo`` and ``inflate`` plan on the means, ``inflate`` with the radius grown by the
        ``eta`` confidence ellipse) and the probability ``effective_eta`` per obstacle.

    Returns
    -------
    WallModel

    """
    from .wall_kernels import wall_conditions, wall_speeds
    mean = ego.position
    eta = config.effective_eta
    delta = 1.0 - eta
    horizon, max_speed, period = config.obstacle_horizon, config.max_speed, config.control_period
    position_cov, actuation_cov, growth = _planning_covariances(ego, config)
    position_cov = np.ascontiguousarray(position_cov)
    spread = _largest_std(position_cov) + horizon * _largest_std(actuation_cov)
    (clearance, far_bounds, walls, discs, wall_radius, wall_distance, disc_radius, disc_distance,
     normals, risks, end_bounds, in_reach, away_normals, away_thresholds, mean0, std0, walk,
     solved) = wall_conditions(
        mean, obstacles.segments, obstacles.frames, obstacles.half_widths,
        obstacles.disc_centres, obstacles.disc_radii, position_cov, actuation_cov,
        ego.radius + config.safety_margin, growth, spread, horizon, max_speed, delta, period,
        _quantile(eta))
    # A partial last period would move less than the walk: cover it whole.
    rounded = period * math.ceil(horizon / period - 1e-9)
    still, approach, close = wall_speeds(mean0, std0, walk, rounded, risks, ndtri(0.5 * solved),
                                         ndtri(solved), wall_distance, wall_radius,
                                         disc_distance, disc_radius, delta)
    return WallModel(
        mean_position=np.array(mean, dtype=float), clearance=clearance, far_bounds=far_bounds,
        segments=obstacles.segments[walls], radius=wall_radius, distance=wall_distance,
        centres=obstacles.disc_centres[discs], disc_radius=disc_radius,
        conditions=LinearConditions(normals=normals, mean0=mean0, std0=std0, walk=walk,
                                    horizon=rounded, still_risk=still, risks=risks,
                                    approach=approach),
        end_bounds=end_bounds, end_in_reach=in_reach, close=close, away_normals=away_normals,
        away_thresholds=away_thresholds, horizon=horizon, max_speed=max_speed,
        position_cov=position_cov, walk_cov=period * actuation_cov)


def rejected_intervals(model, directions):
    """
    Return the open intervals of ``t`` the obstacles reject on each ray.

    Each condition accepts ``[0, upper] U [lower, 1]`` of a ray, a piece rejects where all its
    conditions do, a wall where its support line and a piece both do (three intervals per wall,
    one per disc), a shape close to ``mu`` wherever moving away does not hold:
    :func:`.wall_kernels.rejected_intervals`, compiled. The intervals are exact within
    ``[0, 1]``; beyond it (no command) the parallel tangents are not evaluated.

    Parameters
    ----------
    model : WallModel
        The obstacles.
    directions : numpy.ndarray
        Unit ray directions, shape (M, 2).

    Returns
    -------
    upper, lower : numpy.ndarray
        Shape (3 n + q, M), n near walls and q near discs: rejected ``(upper, lower)`` (empty
        where ``upper >= lower``).

    """
    from .wall_kernels import rejected_intervals as rejected
    conditions = model.conditions
    return rejected(conditions.normals, conditions.approach, conditions.risks,
                    np.ascontiguousarray(directions, dtype=float), model.max_speed,
                    model.mean_position, model.segments, model.radius, model.end_in_reach,
                    model.centres, model.disc_radius, model.close, model.away_normals,
                    model.away_thresholds, model.position_cov, model.walk_cov,
                    conditions.horizon)


def cut_by_walls(gap_ray, lower, upper, first_ray, rejected):
    """
    Feasible intervals minus the walls' rejected open intervals (compiled).

    A point is kept when it lies in one of its ray's feasible intervals and in no rejected
    interval (:func:`.wall_kernels.cut_by_walls`).

    Parameters
    ----------
    gap_ray, lower, upper : numpy.ndarray
        Feasible intervals (ray, lower, upper), shape (G,), sorted by ray and position.
    first_ray : int
        The ray of the rejected intervals' first column.
    rejected : tuple
        ``(upper, lower)`` of :func:`rejected_intervals`, shape (K, M) each; column ``j`` is
        ray ``first_ray + j``.

    Returns
    -------
    ray, lower, upper : numpy.ndarray
        The remaining intervals, ``lower < upper``, sorted by ray and position.

    """
    from .wall_kernels import cut_by_walls as cut
    return cut(gap_ray, lower, upper, first_ray, *rejected)


def segment_distances(points, starts, ends):
    """Distance of points (K, 1, 2) from segments (starts, ends) (.., N, 2): shape (K, N)."""
    along = ends - starts
    length_sq = np.sum(along * along, axis=-1)
    with np.errstate(divide='ignore', invalid='ignore'):
        fraction = np.where(length_sq > 0.0,
                            np.sum((points - starts) * along, axis=-1) / length_sq, 0.0)
    closest = starts + np.clip(fraction, 0.0, 1.0)[..., None] * along
    offset = points - closest
    return np.hypot(offset[..., 0], offset[..., 1])


def wall_intrusion(model, velocities, period):
    """
    How far each command moves into a wall or disc obstacle within one period, shape (K,).

    Per obstacle ``min(d0, R) - d1`` (0 if nowhere), with ``d0`` the distance of ``mu`` and
    ``d1`` the smallest distance of the path ``mu + t v``, ``t in [0, period]``, from the
    segment (or disc centre): the overlap the command creates, or adds to an existing one.
    The largest over the near obstacles (the others are further than ``tau v_max``, which a
    period cannot cover); 0 for ``v = 0``. Compiled: :func:`.wall_kernels.wall_intrusions`.

    Parameters
    ----------
    model : WallModel
        The obstacles.
    velocities : numpy.ndarray
        Candidate commands, shape (K, 2).
    period : float
        How long a command stays in force, seconds.

    """
    from .wall_kernels import wall_intrusions
    return wall_intrusions(np.ascontiguousarray(velocities, dtype=float), model.mean_position,
                           model.segments, model.distance, model.radius, model.centres,
                           model.disc_radius, float(period))


def wall_time_to_contact(model, velocities):
    """
    How long each command takes to reach the nearest support line, capped at tau, shape (K,).

    Per near wall (and disc) ``max(d - R, 0) / (-n.v)`` while approaching (``n.v < 0``, ``n``
    the support line's normal, the disc's middle tangent's), else never; the smallest over
    them, at most ``tau``.
    """
    from .wall_kernels import contact_times
    # The products n.v by numpy's matrix product (BLAS), the rest compiled.
    return contact_times(np.ascontiguousarray(velocities @ model.away_normals.T),
                         model.mean_position, model.distance, model.radius, model.centres,
                         model.disc_radius, float(model.horizon))


def obstacle_probability(model, velocity):
    """
    Return the probability certified against the obstacles at VELOCITY: the smallest over them.

    Per near wall the larger of the support line's and the decomposition's: one minus the
    support line's ``crossing_bounds``, and one minus the sum over the pieces
    of each piece's best condition's (an end out of reach: its a-priori bound); per near disc
    its best tangent's; per shape out of reach one minus its a-priori bound. Clipped to
    [0, 1]; 1 without obstacles.

    """
    from .wall_kernels import largest_failure
    conditions = model.conditions
    failure = largest_failure(
        conditions.normals, conditions.mean0, conditions.std0, conditions.walk,
        conditions.horizon, np.ascontiguousarray(velocity, dtype=float), model.mean_position,
        model.segments, model.radius, model.end_in_reach, model.end_bounds, model.centres,
        model.disc_radius, model.far_bounds, model.position_cov, model.walk_cov)
    return min(max(1.0 - failure, 0.0), 1.0)
