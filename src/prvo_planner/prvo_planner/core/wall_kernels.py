"""
The walls' arithmetic compiled (:mod:`.walls`): geometry, crossing bounds, rejected intervals.

Everything a plan beside walls computes per shape, per condition or per (condition, ray), which
numpy did as tens of calls on arrays of a few to a few hundred elements, here in loops of
scalars. Twelve functions, compiled for one signature each when this module is first imported
(:mod:`.walls` imports it on its first model, :mod:`.probability` on its first array of
margins; the planner node's warm-up imports it before the node spins) and kept in numba's
on-disk cache, as the ray search and the certificate are (``./run.sh setup`` compiles all the
kernel modules once after installing):

* :func:`wall_geometry`: the shapes within reach of the horizon and their linear conditions
  (each near wall's support line, rectangle sides and end fans, each near disc's fan), with
  the risk each is planned with;
* :func:`line_spreads`: each condition's spreads (of the position across its line now, of the
  walk per period) and the risk it is solved at, with the thresholds of moving away;
* :func:`line_speeds`: each condition's bound standing still and the largest speed towards its
  line it accepts (regula falsi on the reflection principle's bound);
* :func:`crossing_bounds`: the reflection principle's bound of each condition at given speeds;
* :func:`largest_failure`: the largest failure bound over the shapes at a velocity;
* :func:`rejected_intervals`: the open intervals of each ray that each shape rejects;
* :func:`cut_by_walls`: the feasible intervals of a plan's rays minus those rejected ones;
* :func:`wall_conditions` and :func:`wall_speeds`: a plan's model in two calls (the geometry,
  the spreads and ``m0``; the speeds and the shapes close to ``mu``), scipy's two ``ndtri``
  calls of the brackets between them;
* :func:`wall_intrusions` and :func:`contact_times`: how far each of the fallback's candidates
  moves into a shape within a period, and how soon it reaches one's line;
* :func:`cantelli_bounds`: Cantelli's bound of an array of margins (the planner's per-plan
  :func:`.probability.eta_from_k`), beside the walls for want of a module of the plan's own.

``Phi`` and ``erfcx`` are :mod:`.special_kernels`' (scipy's ufuncs cannot be called from numba):
``Phi`` within 2e-14 of scipy's, ``erfcx`` within a few ulps, so a bound moves by rounding only.
"""

import math

from numba import types
import numpy as np

from .ray_solver import (
    READ_ONLY_CUBE,
    READ_ONLY_INDICES,
    READ_ONLY_ROWS,
    READ_ONLY_VECTOR,
    _fma,
    jit,
)
from .special_kernels import erfcx, ndtr
from .walls import FAN, FAN_HALF, PER_WALL, REACH_SHARE

_SQRT2 = math.sqrt(2.0)
# Steps of regula falsi (Illinois) for the largest speed towards a line a condition accepts:
# the bracket is already (z(delta / 2) - z(delta)) S / tau wide (a few mm/s) and the bound is
# smooth and monotone in it, so a few steps leave it far below any speed's meaning.
_FALSI_STEPS = 8

_VECTOR = types.float64[::1]
_ROWS = types.float64[:, ::1]
_BOUNDS_SIGNATURE = _VECTOR(_VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR)
_SPEEDS_SIGNATURE = types.Tuple((_VECTOR, _VECTOR))(
    _VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR, _VECTOR, _VECTOR)
_SPREADS_SIGNATURE = types.Tuple((_VECTOR, _VECTOR, _VECTOR, _VECTOR))(
    READ_ONLY_ROWS, READ_ONLY_ROWS, READ_ONLY_ROWS, READ_ONLY_ROWS, types.float64,
    READ_ONLY_VECTOR, types.float64)
_FAILURE_SIGNATURE = types.float64(
    _ROWS, _VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR, _VECTOR, types.float64[:, :, ::1],
    _VECTOR, types.boolean[:, ::1], _ROWS, _ROWS, _VECTOR, _VECTOR, _ROWS, _ROWS)
_INDICES = types.int64[::1]
# The obstacles' arrays are read-only (``StaticObstacles``), as is a belief's mean.
_GEOMETRY_SIGNATURE = types.Tuple((
    types.float64, _VECTOR, _INDICES, _INDICES, _VECTOR, _VECTOR, _VECTOR, _VECTOR, _ROWS,
    _VECTOR, _VECTOR, _ROWS, types.boolean[:, ::1], _ROWS))(
    READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_ROWS, READ_ONLY_VECTOR,
    READ_ONLY_ROWS, READ_ONLY_VECTOR, types.float64, types.float64, types.float64, types.float64,
    types.float64, types.float64)
_REJECTED_SIGNATURE = types.Tuple((_ROWS, _ROWS))(
    _ROWS, _VECTOR, _VECTOR, _ROWS, types.float64, _VECTOR, types.float64[:, :, ::1], _VECTOR,
    types.boolean[:, ::1], _ROWS, _VECTOR, types.boolean[::1], _ROWS, _VECTOR, _ROWS, _ROWS,
    types.float64)
_CUT_SIGNATURE = types.Tuple((_INDICES, _VECTOR, _VECTOR))(
    READ_ONLY_INDICES, READ_ONLY_VECTOR, READ_ONLY_VECTOR, types.int64, READ_ONLY_ROWS,
    READ_ONLY_ROWS)
# wall_conditions: wall_geometry's outputs, then mean0, std0, walk, solved risks, thresholds.
_CONDITIONS_SIGNATURE = types.Tuple((
    types.float64, _VECTOR, _INDICES, _INDICES, _VECTOR, _VECTOR, _VECTOR, _VECTOR, _ROWS,
    _VECTOR, _ROWS, types.boolean[:, ::1], _ROWS, _VECTOR, _VECTOR, _VECTOR, _VECTOR,
    _VECTOR))(
    READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_ROWS,
    READ_ONLY_VECTOR, READ_ONLY_ROWS, READ_ONLY_ROWS, types.float64, types.float64,
    types.float64, types.float64, types.float64, types.float64, types.float64, types.float64)
# Its arguments are wall_conditions' and scipy's outputs, as line_speeds' are: writable.
_CLOSE_SIGNATURE = types.Tuple((_VECTOR, _VECTOR, types.boolean[::1]))(
    _VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR, _VECTOR, _VECTOR, _VECTOR, _VECTOR,
    _VECTOR, _VECTOR, types.float64)
_INTRUSION_SIGNATURE = _VECTOR(
    READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_VECTOR,
    READ_ONLY_ROWS, READ_ONLY_VECTOR, types.float64)
_CONTACT_SIGNATURE = _VECTOR(
    READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_ROWS,
    READ_ONLY_VECTOR, types.float64)
_CANTELLI_SIGNATURE = types.Tuple((_VECTOR, types.boolean))(READ_ONLY_VECTOR, types.boolean)
# From this k on k^2 / (1 + k^2) is exactly 1 (``probability._CERTAIN_K``).
_CERTAIN_K = 1e8


@jit(inline='always')
def _below_zero(mean, std):
    """``P(N(mean, std^2) < 0)``; a known value (std 0) gives 0 or 1."""
    if std > 0.0:
        return ndtr(-(mean / std))
    return 0.0 if mean >= 0.0 else 1.0


@jit(inline='always')
def _crossing_bound(mean0, std0, walk, horizon, approach):
    """
    Bound on ``P(min over [0, horizon] of y(t) < 0)`` for ``y(t) = y0 - approach t + W(t)``.

    ``y0 ~ N(mean0, std0^2)`` and ``W`` a Brownian motion of variance ``walk`` per second,
    independent of ``y0``; ``approach >= 0``. With ``t0 = std0^2 / walk``, ``y`` on
    ``[0, horizon]`` is the restriction of a Brownian motion with the same drift started at
    ``x0 = mean0 + approach t0`` at time ``-t0``, so the reflection principle over
    ``[-t0, horizon]`` bounds it:
    ``Phi(-(mean0 - approach horizon) / S) + exp(2 approach x0 / walk) Phi(-u)``, with
    ``S^2 = std0^2 + walk horizon`` and ``u = (mean0 + approach (horizon + 2 t0)) / S``. The
    second term is computed as ``phi((mean0 - approach horizon) / S) sqrt(pi / 2)
    erfcx(u / sqrt(2))`` (the same number, without the overflow). Without a walk the path is
    straight and the bound is exact: ``P(y0 < approach horizon)``. In [0, 1].
    """
    reach = mean0 - approach * horizon
    spread = math.sqrt(std0 * std0 + walk * horizon)
    first = _below_zero(reach, spread)
    if not walk > 0.0:
        return first
    before = std0 * std0 / walk
    if not mean0 + approach * before > 0.0:
        # x0 <= 0: the walk starts on the wrong side of the line.
        return 1.0
    # Only a drift towards the line makes u depend on t0 (inf for a vanishing walk).
    far = mean0 + (approach * (horizon + 2.0 * before) if approach > 0.0 else 0.0)
    ratio = reach / spread
    # phi(ratio) sqrt(pi / 2) = exp(-ratio^2 / 2) / 2.
    second = 0.5 * math.exp(-0.5 * ratio * ratio) * erfcx(max(far, 0.0) / (spread * _SQRT2))
    return min(max(first + second, 0.0), 1.0)


@jit(_BOUNDS_SIGNATURE)
def crossing_bounds(mean0, std0, walk, horizon, approach):
    """
    Return each condition's crossing bound, shape (K,).

    Parameters
    ----------
    mean0, std0, walk : numpy.ndarray
        ``y0``'s mean and std and the walk's variance per second, shape (K,) each.
    horizon : float
        ``tau`` [s].
    approach : numpy.ndarray
        The speed towards each line, ``>= 0``, shape (K,).

    Returns
    -------
    numpy.ndarray
        ``P(min over [0, tau] of y(t) < 0)`` bounded (:func:`_crossing_bound`), shape (K,).

    """
    bounds = mean0.copy()
    for index in range(mean0.size):
        bounds[index] = _crossing_bound(mean0[index], std0[index], walk[index], horizon,
                                        approach[index])
    return bounds


@jit(inline='always')
def _at_least_zero(value):
    """``max(value, 0)`` as numpy's ``maximum``: NaN and -0.0 kept."""
    return 0.0 if value < 0.0 else value


@jit(_SPREADS_SIGNATURE)
def line_spreads(normals, away_normals, position_cov, actuation_cov, period, risks, quantile):
    """
    Return each condition's spreads and solved risk, and the thresholds of moving away.

    Parameters
    ----------
    normals : numpy.ndarray
        The conditions' normals ``n``, shape (K, 2).
    away_normals : numpy.ndarray
        Per near shape the normal of moving away, shape (S, 2).
    position_cov, actuation_cov : numpy.ndarray
        ``S_p`` and ``S_a``, shape (2, 2).
    period : float
        The control period ``T`` [s].
    risks : numpy.ndarray
        The risk each condition is planned with, shape (K,).
    quantile : float
        ``Phi^-1(eta)``.

    Returns
    -------
    std0, walk, solved : numpy.ndarray
        ``sqrt(n' S_p n)``, ``T n' S_a n`` and the risk clipped to ``[1e-300, 1]``, shape (K,)
        each.
    away : numpy.ndarray
        ``Phi^-1(eta) sqrt(n' S_a n)`` per away normal, shape (S,).

    """
    count = normals.shape[0]
    std0, walk, solved = np.empty(count), np.empty(count), np.empty(count)
    for index in range(count):
        x, y = normals[index, 0], normals[index, 1]
        std0[index] = np.sqrt(_at_least_zero(position_cov[0, 0] * x * x
                                              + 2.0 * position_cov[0, 1] * x * y
                                              + position_cov[1, 1] * y * y))
        walk[index] = period * _at_least_zero(actuation_cov[0, 0] * x * x
                                              + 2.0 * actuation_cov[0, 1] * x * y
                                              + actuation_cov[1, 1] * y * y)
        risk = risks[index]
        risk = 1e-300 if risk < 1e-300 else risk
        solved[index] = 1.0 if risk > 1.0 else risk
    away = np.empty(away_normals.shape[0])
    for index in range(away.shape[0]):
        x, y = away_normals[index, 0], away_normals[index, 1]
        away[index] = quantile * np.sqrt(_at_least_zero(actuation_cov[0, 0] * x * x
                                                        + 2.0 * actuation_cov[0, 1] * x * y
                                                        + actuation_cov[1, 1] * y * y))
    return std0, walk, solved, away


@jit(_SPEEDS_SIGNATURE)
def line_speeds(mean0, std0, walk, horizon, risks, low_quantiles, high_quantiles):
    """
    Return each condition's bound standing still and the largest speed towards it accepted.

    The bound rises with the speed towards the line. The reflected term is at most the first
    (Mills' ratio falls and ``u >= (m0 - a tau) / S``), so the bound lies between the first term
    and twice it: the speed lies between the first term's thresholds at half the risk
    (accepted) and at the risk (not), ``low, high = max(m0 + q S, 0) / tau`` with ``q`` the
    normal quantiles of those risks and ``S = sqrt(s0^2 + walk tau)``. Where the bound standing
    still is below the risk and the bracket ``[low, high]`` is not empty, regula falsi with the
    Illinois rule narrows it for ``_FALSI_STEPS`` steps, from below: the answer is always a
    speed where the bound holds (``low`` at worst). The end kept twice in a row has its value
    halved, so that both ends move.

    Parameters
    ----------
    mean0, std0, walk : numpy.ndarray
        As :func:`crossing_bounds`, shape (K,) each.
    horizon : float
        ``tau`` [s].
    risks : numpy.ndarray
        The risk each condition is planned with, shape (K,).
    low_quantiles, high_quantiles : numpy.ndarray
        ``Phi^-1`` of half the risk and of the risk (clipped to ``[1e-300, 1]``), shape (K,).

    Returns
    -------
    still, approach : numpy.ndarray
        The bound standing still, and the largest speed towards the line accepted (``-inf``
        where standing still is not: ``still >= risk``), shape (K,) each.

    """
    still = mean0.copy()
    approach = mean0.copy()
    for index in range(mean0.size):
        m0, s0, w, limit = mean0[index], std0[index], walk[index], risks[index]
        spread = np.sqrt(s0 * s0 + w * horizon)
        lower = _at_least_zero(m0 + low_quantiles[index] * spread) / horizon
        upper = _at_least_zero(m0 + high_quantiles[index] * spread) / horizon
        approach[index] = lower
        still[index] = _crossing_bound(m0, s0, w, horizon, 0.0)
        if not still[index] < limit:
            approach[index] = -math.inf
            continue
        if not upper > lower:
            continue
        below = _crossing_bound(m0, s0, w, horizon, lower) - limit
        above = _crossing_bound(m0, s0, w, horizon, upper) - limit
        last = 0
        for _ in range(_FALSI_STEPS):
            gap = above - below
            middle = upper - above * (upper - lower) / gap if gap > 0.0 else 0.5 * (lower
                                                                                     + upper)
            middle = min(max(middle, lower), upper)
            value = _crossing_bound(m0, s0, w, horizon, middle) - limit
            if value <= 0.0:
                below = value
                if last == 1:
                    above *= 0.5
                lower = middle
                last = 1
            else:
                if last == -1:
                    below *= 0.5
                above = value
                upper = middle
                last = -1
        approach[index] = lower
    return still, approach


@jit(inline='always')
def _half_line(slope, bound):
    """
    Return where ``slope t >= bound`` holds, as ``[0, upper] U [lower, 1]``: (upper, lower).

    ``upper`` is ``-inf`` (``lower`` ``inf``) where that part is empty.
    """
    if slope < 0.0:
        return bound / slope, math.inf
    if slope > 0.0:
        return -math.inf, bound / slope
    return (math.inf if bound <= 0.0 else -math.inf), math.inf


@jit(inline='always')
def _quadratic_form(x, y, cov):
    """Return ``n' S n`` for the normal (x, y) and a 2x2 covariance S, at least 0."""
    return max(cov[0, 0] * x * x + 2.0 * cov[0, 1] * x * y + cov[1, 1] * y * y, 0.0)


@jit(inline='always')
def _parallel_failure(mean, centre_x, centre_y, radius, e_x, e_y, position_cov, walk_cov,
                      horizon):
    """
    Return the crossing bound of a disc's tangent parallel to the unit direction ``e``.

    Its normal is across ``e``, on the side of ``mu``; moving along ``e`` keeps the distance to
    it, so it has no approach: the margin ``|n.(mu - c)| - R`` and the spreads across ``e``.
    """
    across_x, across_y = -e_y, e_x
    side = (mean[0] - centre_x) * across_x + (mean[1] - centre_y) * across_y
    return _crossing_bound(abs(side) - radius,
                           math.sqrt(_quadratic_form(across_x, across_y, position_cov)),
                           _quadratic_form(across_x, across_y, walk_cov), horizon, 0.0)


@jit(inline='always')
def _condition(normals, approach, index, e_x, e_y, max_speed):
    """Return condition INDEX's accepted ``(upper, lower)`` on the ray ``e``: ``n.v >= -a``."""
    return _half_line(max_speed * (normals[index, 0] * e_x + normals[index, 1] * e_y),
                      -approach[index])


@jit(inline='always')
def _fan_rejects(normals, approach, first, e_x, e_y, max_speed):
    """Return a fan's rejected ``(upper, lower)``: where every one of its FAN tangents does."""
    upper, lower = -math.inf, math.inf
    for index in range(first, first + FAN):
        one_upper, one_lower = _condition(normals, approach, index, e_x, e_y, max_speed)
        upper, lower = max(upper, one_upper), min(lower, one_lower)
    return upper, lower


@jit(inline='always')
def _counts(upper, lower):
    """Whether the open interval ``(upper, lower)`` of ``t`` is not empty and meets ``(0, 1)``."""
    return upper < lower and lower > 0.0 and upper < 1.0


@jit(_REJECTED_SIGNATURE)
def rejected_intervals(normals, approach, risks, directions, max_speed, mean, segments, radius,
                       end_in_reach, centres, disc_radius, close, away_normals,
                       away_thresholds, position_cov, walk_cov, horizon):
    """
    Return the open intervals of ``t`` the near walls and discs reject on each ray.

    Each condition accepts ``[0, upper] U [lower, 1]`` of a ray; a piece (any of its
    conditions) rejects where all of them do: the largest ``upper``, the smallest ``lower``.
    Per wall the pieces are the rectangle (its four sides) and the two end discs (a fan each,
    or on a ray its parallel tangent, which accepts all of it when it holds at the end's share
    of the risk; an end out of reach rejects nothing), and the wall rejects where the support
    line and a piece both do: three intervals. A disc rejects where its fan does, unless its
    parallel tangent holds at its risk. A shape close to ``mu`` accepts only moving away,
    ``v_max (n.e) t >= Phi^-1(eta) sqrt(n' S_a n)``.

    The parallel tangents, most of this function's arithmetic, are evaluated only where the
    piece's interval without them is not empty and meets ``(0, 1)``: elsewhere the interval is
    returned as it is, empty or beyond every command (``t`` outside ``[0, 1]``), and
    :func:`cut_by_walls` passes over it as it passed over the tangent's ``(inf, lower)``.

    Parameters
    ----------
    normals, approach, risks : numpy.ndarray
        The conditions (:class:`.walls.LinearConditions`): per near wall ``5 + 2 FAN`` (the
        support line, the rectangle's four sides, the start's fan, the end's), then per near
        disc its fan; shapes (C, 2), (C,), (C,).
    directions : numpy.ndarray
        Unit ray directions, shape (M, 2).
    max_speed : float
        ``v_max``.
    mean : numpy.ndarray
        ``mu``, shape (2,).
    segments, radius, end_in_reach : numpy.ndarray
        The near walls (n, 2, 2), their grown radius (n,), whether each end is in reach (n, 2).
    centres, disc_radius : numpy.ndarray
        The near discs (q, 2) and their grown radius (q,).
    close, away_normals, away_thresholds : numpy.ndarray
        Per wall then disc: only moving away accepted (n + q,), its normal (n + q, 2) and
        threshold (n + q,).
    position_cov, walk_cov : numpy.ndarray
        ``S_p`` and ``T S_a``, shape (2, 2).
    horizon : float
        ``tau`` in whole periods [s].

    Returns
    -------
    upper, lower : numpy.ndarray
        Shape (3 n + q, M): rejected ``(upper, lower)`` (empty where ``upper >= lower``), three
        per wall (with the rectangle, the start, the end), then one per disc; exact within
        ``[0, 1]``.

    """
    walls, discs, rays = radius.size, disc_radius.size, directions.shape[0]
    upper = np.empty((3 * walls + discs, rays))
    lower = np.empty((3 * walls + discs, rays))
    for wall in range(walls):
        first = wall * PER_WALL
        for ray in range(rays):
            e_x, e_y = directions[ray, 0], directions[ray, 1]
            if close[wall]:
                away_upper, away_lower = _half_line(
                    max_speed * (away_normals[wall, 0] * e_x + away_normals[wall, 1] * e_y),
                    away_thresholds[wall])
                for piece in range(3):
                    upper[3 * wall + piece, ray] = away_upper
                    lower[3 * wall + piece, ray] = away_lower
                continue
            support_upper, support_lower = _condition(normals, approach, first, e_x, e_y,
                                                      max_speed)
            piece_upper, piece_lower = -math.inf, math.inf
            for index in range(first + 1, first + 5):
                one_upper, one_lower = _condition(normals, approach, index, e_x, e_y,
                                                  max_speed)
                piece_upper, piece_lower = max(piece_upper, one_upper), min(piece_lower,
                                                                           one_lower)
            upper[3 * wall, ray] = max(support_upper, piece_upper)
            lower[3 * wall, ray] = min(support_lower, piece_lower)
            for end in range(2):
                fan = first + 5 + end * FAN
                piece_upper, piece_lower = _fan_rejects(normals, approach, fan, e_x, e_y,
                                                        max_speed)
                start = max(support_upper, piece_upper)
                stop = min(support_lower, piece_lower)
                if not end_in_reach[wall, end] or (_counts(start, stop) and _parallel_failure(
                        mean, segments[wall, end, 0], segments[wall, end, 1], radius[wall], e_x,
                        e_y, position_cov, walk_cov, horizon) <= risks[fan]):
                    start = math.inf
                upper[3 * wall + 1 + end, ray] = start
                lower[3 * wall + 1 + end, ray] = stop
    for disc in range(discs):
        first, row = walls * PER_WALL + disc * FAN, 3 * walls + disc
        for ray in range(rays):
            e_x, e_y = directions[ray, 0], directions[ray, 1]
            if close[walls + disc]:
                upper[row, ray], lower[row, ray] = _half_line(
                    max_speed * (away_normals[walls + disc, 0] * e_x
                                 + away_normals[walls + disc, 1] * e_y),
                    away_thresholds[walls + disc])
                continue
            upper[row, ray], lower[row, ray] = _fan_rejects(normals, approach, first, e_x, e_y,
                                                            max_speed)
            if _counts(upper[row, ray], lower[row, ray]) and _parallel_failure(
                    mean, centres[disc, 0], centres[disc, 1], disc_radius[disc], e_x, e_y,
                    position_cov, walk_cov, horizon) <= risks[first]:
                upper[row, ray] = math.inf
    return upper, lower


@jit(inline='always')
def _reach_bound(distance, radius, spread, horizon, max_speed):
    """A-priori bound on the path entering a shape at DISTANCE (of grown RADIUS) within tau."""
    gap = distance - radius - horizon * max_speed
    if not gap > 0.0:
        return 1.0
    if spread == 0.0:
        return 0.0
    return min(2.0 * math.exp(-0.5 * (gap / spread) ** 2), 1.0)


@jit(inline='always')
def _write_fan(mean, centre_x, centre_y, radius, normals, offsets, first):
    """
    Write a disc's fan of tangents into rows FIRST.. of NORMALS and OFFSETS; return ``|mu - c|``.

    The normals are the FAN directions within ``arccos(R / d)`` of the direction from the
    centre to ``mu`` (all of them that direction when ``mu`` is inside the disc), the tangent
    lines ``n.x = n.c + R``.
    """
    offset_x, offset_y = mean[0] - centre_x, mean[1] - centre_y
    distance = math.hypot(offset_x, offset_y)
    heading = math.atan2(offset_y, offset_x)
    opening = math.acos(radius / distance if distance > radius else 1.0)
    for step in range(FAN):
        angle = heading + opening * ((step - FAN_HALF) / FAN_HALF)
        normal_x, normal_y = math.cos(angle), math.sin(angle)
        normals[first + step, 0], normals[first + step, 1] = normal_x, normal_y
        offsets[first + step] = normal_x * centre_x + normal_y * centre_y + radius
    return distance


@jit(_GEOMETRY_SIGNATURE)
def wall_geometry(mean, segments, frames, half_widths, disc_centres, disc_radii, base_radius,
                  growth, spread, horizon, max_speed, delta):
    """
    Return one plan's shapes within reach and their linear conditions (:func:`.walls.wall_model`).

    Each shape's distance from ``mu`` and grown radius ``R`` (``base_radius`` plus its
    half-width or radius, plus ``growth``) give its a-priori bound of being entered within the
    horizon; a shape is near where that bound exceeds ``REACH_SHARE delta``. Per near wall the
    conditions are the support line (normal from the closest point to ``mu``, or across the wall
    from a point on it), the rectangle's four sides and each end disc's fan; an end whose own
    a-priori bound is at most ``REACH_SHARE delta`` is out of reach and charged that bound, and
    the rest of ``delta`` is shared by the rectangle and the ends within reach. Per near disc,
    its fan at ``delta``.

    Parameters
    ----------
    mean : numpy.ndarray
        ``mu``, shape (2,).
    segments, frames, half_widths : numpy.ndarray
        Every wall (N, 2, 2), its frame (``StaticObstacles.frames``, (N, 6)), half-width (N,).
    disc_centres, disc_radii : numpy.ndarray
        Every disc obstacle, (D, 2) and (D,).
    base_radius, growth : float
        The ego's radius plus the safety margin, and the model's growth of it (``inflate``).
    spread, horizon, max_speed, delta : float
        ``sigma_p + tau sigma_a`` (largest stds), ``tau``, ``v_max``, the risk ``1 - eta``.

    Returns
    -------
    clearance : float
        Smallest ``distance - R`` before the growth (``inf`` without shapes).
    far_bounds : numpy.ndarray
        A-priori bounds of the shapes out of reach, walls then discs, (F,).
    walls, discs : numpy.ndarray
        Indices of the near walls (n,) and near discs (q,).
    wall_radius, wall_distance, disc_radius, disc_distance : numpy.ndarray
        Their grown radius and distance from ``mu``, (n,), (n,), (q,), (q,).
    normals, offsets, risks : numpy.ndarray
        The conditions, ``n (5 + 2 FAN) + q FAN`` of them: (C, 2), (C,), (C,).
    end_bounds, end_in_reach : numpy.ndarray
        Per near wall and end, the bound charged (0 within reach) and whether in reach, (n, 2).
    away_normals : numpy.ndarray
        Per near wall its support normal, per near disc its fan's middle normal, (n + q, 2).

    """
    count, disc_count = half_widths.size, disc_radii.size
    distance = np.empty(count + disc_count)
    radius = np.empty(count + disc_count)
    closest = np.empty((count, 2))
    clearance = math.inf
    for wall in range(count):
        along = min(max(frames[wall, 0] * mean[0] + frames[wall, 1] * mean[1], frames[wall, 4]),
                    frames[wall, 5])
        closest[wall, 0] = segments[wall, 0, 0] + (along - frames[wall, 4]) * frames[wall, 0]
        closest[wall, 1] = segments[wall, 0, 1] + (along - frames[wall, 4]) * frames[wall, 1]
        distance[wall] = math.hypot(mean[0] - closest[wall, 0], mean[1] - closest[wall, 1])
        radius[wall] = base_radius + half_widths[wall]
    for disc in range(disc_count):
        distance[count + disc] = math.hypot(mean[0] - disc_centres[disc, 0],
                                            mean[1] - disc_centres[disc, 1])
        radius[count + disc] = base_radius + disc_radii[disc]
    bounds = np.empty(count + disc_count)
    near = np.empty(count + disc_count, dtype=np.bool_)
    for shape in range(count + disc_count):
        clearance = min(clearance, distance[shape] - radius[shape])
        radius[shape] += growth
        bounds[shape] = _reach_bound(distance[shape], radius[shape], spread, horizon, max_speed)
        near[shape] = bounds[shape] > REACH_SHARE * delta
    walls = np.flatnonzero(near[:count])
    discs = np.flatnonzero(near[count:])
    far_bounds = bounds[~near]
    near_count, near_discs = walls.size, discs.size
    size = near_count * PER_WALL + near_discs * FAN
    normals = np.empty((size, 2))
    offsets = np.empty(size)
    risks = np.empty(size)
    end_bounds = np.zeros((near_count, 2))
    end_in_reach = np.zeros((near_count, 2), dtype=np.bool_)
    away_normals = np.empty((near_count + near_discs, 2))
    for row in range(near_count):
        wall = walls[row]
        grown, first = radius[wall], row * PER_WALL
        across_x, across_y = frames[wall, 2], frames[wall, 3]
        support_x, support_y = across_x, across_y
        if distance[wall] > 0.0:
            support_x = (mean[0] - closest[wall, 0]) / distance[wall]
            support_y = (mean[1] - closest[wall, 1]) / distance[wall]
        away_normals[row, 0], away_normals[row, 1] = support_x, support_y
        start_x, start_y = segments[wall, 0, 0], segments[wall, 0, 1]
        end_x, end_y = segments[wall, 1, 0], segments[wall, 1, 1]
        across_side = across_x * start_x + across_y * start_y
        sides = ((support_x, support_y), (across_x, across_y), (-across_x, -across_y),
                 (-frames[wall, 0], -frames[wall, 1]), (frames[wall, 0], frames[wall, 1]))
        for side in range(5):
            normals[first + side, 0], normals[first + side, 1] = sides[side]
        offsets[first] = max(support_x * start_x + support_y * start_y,
                             support_x * end_x + support_y * end_y) + grown
        offsets[first + 1] = across_side + grown
        offsets[first + 2] = grown - across_side
        offsets[first + 3] = -frames[wall, 4]
        offsets[first + 4] = frames[wall, 5]
        for end in range(2):
            end_distance = _write_fan(mean, segments[wall, end, 0], segments[wall, end, 1], grown,
                                   normals, offsets, first + 5 + end * FAN)
            bound = _reach_bound(end_distance, grown, spread, horizon, max_speed)
            end_in_reach[row, end] = bound > REACH_SHARE * delta
            if not end_in_reach[row, end]:
                end_bounds[row, end] = bound
        share = (delta - (end_bounds[row, 0] + end_bounds[row, 1])) / (
            1.0 + (int(end_in_reach[row, 0]) + int(end_in_reach[row, 1])))
        risks[first] = delta
        for side in range(1, 5):
            risks[first + side] = share
        for end in range(2):
            for step in range(FAN):
                risks[first + 5 + end * FAN + step] = share if end_in_reach[row, end] else 0.0
    disc_radius = np.empty(near_discs)
    disc_distance = np.empty(near_discs)
    for row in range(near_discs):
        disc, first = discs[row], near_count * PER_WALL + row * FAN
        disc_radius[row] = radius[count + disc]
        disc_distance[row] = _write_fan(mean, disc_centres[disc, 0], disc_centres[disc, 1],
                                     disc_radius[row], normals, offsets, first)
        for step in range(FAN):
            risks[first + step] = delta
        away_normals[near_count + row, 0] = normals[first + FAN_HALF, 0]
        away_normals[near_count + row, 1] = normals[first + FAN_HALF, 1]
    return (clearance, far_bounds, walls, discs, radius[:count][walls], distance[:count][walls],
            disc_radius, disc_distance, normals, offsets, risks, end_bounds, end_in_reach,
            away_normals)


@jit(_FAILURE_SIGNATURE)
def largest_failure(normals, mean0, std0, walk, horizon, velocity, mean, segments, radius,
                    end_in_reach, end_bounds, centres, disc_radius, far_bounds, position_cov,
                    walk_cov):
    """
    Return the largest failure bound over the obstacles at VELOCITY (0 without any).

    Each condition fails at most with its crossing bound at the speed ``max(-n.v, 0)`` towards
    its line. A near wall fails at most with the smaller of its support line's bound and the
    decomposition's, the sum over its pieces of each piece's best condition's (an end out of
    reach: its a-priori bound); a near disc with its best tangent's; moving, the tangents
    parallel to the motion count for the ends and discs too. A shape out of reach fails at most
    with its a-priori bound.

    Parameters
    ----------
    normals, mean0, std0, walk : numpy.ndarray
        The conditions (:class:`.walls.LinearConditions`), (C, 2), (C,), (C,), (C,).
    horizon : float
        ``tau`` in whole periods [s].
    velocity, mean : numpy.ndarray
        The command ``v`` and ``mu``, shape (2,) each.
    segments, radius, end_in_reach, end_bounds : numpy.ndarray
        The near walls (n, 2, 2), their grown radius (n,), and per end whether it is in reach
        and the bound charged otherwise, (n, 2) each.
    centres, disc_radius : numpy.ndarray
        The near discs (q, 2) and their grown radius (q,).
    far_bounds : numpy.ndarray
        The a-priori bounds of the shapes out of reach, (F,).
    position_cov, walk_cov : numpy.ndarray
        ``S_p`` and ``T S_a``, shape (2, 2).

    """
    speed = math.hypot(velocity[0], velocity[1])
    moving = speed > 0.0
    e_x, e_y = (velocity[0] / speed, velocity[1] / speed) if moving else (0.0, 0.0)
    failures = np.empty(mean0.size)
    for index in range(mean0.size):
        failures[index] = _crossing_bound(
            mean0[index], std0[index], walk[index], horizon,
            max(-(normals[index, 0] * velocity[0] + normals[index, 1] * velocity[1]), 0.0))
    largest = 0.0
    for bound in far_bounds:
        largest = max(largest, bound)
    for wall in range(radius.size):
        first = wall * PER_WALL
        rectangle = min(min(failures[first + 1], failures[first + 2]),
                        min(failures[first + 3], failures[first + 4]))
        ends = np.empty(2)
        for end in range(2):
            if not end_in_reach[wall, end]:
                ends[end] = end_bounds[wall, end]
                continue
            best = 1.0
            for index in range(first + 5 + end * FAN, first + 5 + (end + 1) * FAN):
                best = min(best, failures[index])
            if moving:
                best = min(best, _parallel_failure(
                    mean, segments[wall, end, 0], segments[wall, end, 1], radius[wall], e_x,
                    e_y, position_cov, walk_cov, horizon))
            ends[end] = best
        largest = max(largest, min(failures[first], rectangle + (ends[0] + ends[1])))
    for disc in range(disc_radius.size):
        first = radius.size * PER_WALL + disc * FAN
        best = 1.0
        for index in range(first, first + FAN):
            best = min(best, failures[index])
        if moving:
            best = min(best, _parallel_failure(mean, centres[disc, 0], centres[disc, 1],
                                               disc_radius[disc], e_x, e_y, position_cov,
                                               walk_cov, horizon))
        largest = max(largest, best)
    return largest


@jit(_CUT_SIGNATURE)
def cut_by_walls(gap_ray, lower, upper, first_ray, wall_upper, wall_lower):
    """
    Feasible intervals minus the walls' rejected open intervals, sorted by ray and position.

    A point of a ray is kept when it lies in one of the ray's feasible intervals (disjoint,
    closed) and in no rejected open interval; pieces of no length are dropped. A rejected
    interval counts where it is not empty and meets ``(0, 1)``.

    Parameters
    ----------
    gap_ray, lower, upper : numpy.ndarray
        Feasible intervals (ray, lower, upper), shape (G,), sorted by ray and position.
    first_ray : int
        The ray of the rejected intervals' first column.
    wall_upper, wall_lower : numpy.ndarray
        Rejected open intervals ``(upper, lower)`` per shape and ray, shape (K, M): column
        ``j`` is ray ``first_ray + j``.

    Returns
    -------
    ray, lower, upper : numpy.ndarray
        The remaining intervals, ``lower < upper``.

    """
    count = gap_ray.shape[0]
    shapes = wall_upper.shape[0]
    # Each rejected interval splits at most one piece in two.
    capacity = count * (shapes + 1)
    out_ray = np.empty(capacity, dtype=np.int64)
    out_lower = np.empty(capacity)
    out_upper = np.empty(capacity)
    starts = np.empty(shapes)
    ends = np.empty(shapes)
    pieces = 0
    first = 0
    while first < count:
        ray = gap_ray[first]
        stop = first + 1
        while stop < count and gap_ray[stop] == ray:
            stop += 1
        column = ray - first_ray
        # The ray's rejected intervals that count, by their starts (insertion sort: a few).
        rejected = 0
        for shape in range(shapes):
            start, end = wall_upper[shape, column], wall_lower[shape, column]
            if start < end and end > 0.0 and start < 1.0:
                start, end = max(start, -1.0), min(end, 2.0)
                place = rejected
                while place > 0 and starts[place - 1] > start:
                    starts[place], ends[place] = starts[place - 1], ends[place - 1]
                    place -= 1
                starts[place], ends[place] = start, end
                rejected += 1
        for gap in range(first, stop):
            position, end = lower[gap], upper[gap]
            for index in range(rejected):
                if starts[index] >= end:
                    break
                if ends[index] <= position:
                    continue
                if starts[index] > position:
                    out_ray[pieces] = ray
                    out_lower[pieces] = position
                    out_upper[pieces] = starts[index]
                    pieces += 1
                position = ends[index]
                if position >= end:
                    break
            if position < end:
                out_ray[pieces] = ray
                out_lower[pieces] = position
                out_upper[pieces] = end
                pieces += 1
        first = stop
    return out_ray[:pieces].copy(), out_lower[:pieces].copy(), out_upper[:pieces].copy()


@jit(_CONDITIONS_SIGNATURE)
def wall_conditions(mean, segments, frames, half_widths, disc_centres, disc_radii, position_cov,
                    actuation_cov, base_radius, growth, spread, horizon, max_speed, delta, period,
                    quantile):
    """
    Return one plan's near shapes and their conditions' spreads (:func:`.walls.wall_model`).

    :func:`wall_geometry`, then :func:`line_spreads` of its conditions, and each condition's
    ``m0 = n.mu - c``, in one call. ``n.mu`` is rounded as numpy's matrix product rounds it
    here (one fused multiply-add over the product of the second coordinates), so that the
    walls' plans stay what they were.

    Parameters
    ----------
    mean, segments, frames, half_widths, disc_centres, disc_radii : numpy.ndarray
        As :func:`wall_geometry`.
    position_cov, actuation_cov : numpy.ndarray
        ``S_p`` and ``S_a`` as planned with, shape (2, 2).
    base_radius, growth, spread, horizon, max_speed, delta : float
        As :func:`wall_geometry`.
    period, quantile : float
        ``T`` and ``Phi^-1(eta)``, as :func:`line_spreads`.

    Returns
    -------
    tuple
        :func:`wall_geometry`'s outputs without the offsets (``clearance``, ``far_bounds``,
        ``walls``, ``discs``, ``wall_radius``, ``wall_distance``, ``disc_radius``,
        ``disc_distance``, ``normals``, ``risks``, ``end_bounds``, ``end_in_reach``,
        ``away_normals``), then :func:`line_spreads`' ``away`` thresholds, then ``mean0``,
        ``std0``, ``walk`` and the solved risks, shape (C,) each.

    """
    (clearance, far_bounds, walls, discs, wall_radius, wall_distance, disc_radius,
     disc_distance, normals, offsets, risks, end_bounds, end_in_reach,
     away_normals) = wall_geometry(mean, segments, frames, half_widths, disc_centres, disc_radii,
                                   base_radius, growth, spread, horizon, max_speed, delta)
    std0, walk, solved, away = line_spreads(normals, away_normals, position_cov, actuation_cov,
                                            period, risks, quantile)
    mean0 = np.empty(offsets.size)
    for index in range(offsets.size):
        mean0[index] = _fma(normals[index, 0], mean[0], normals[index, 1] * mean[1]) \
            - offsets[index]
    return (clearance, far_bounds, walls, discs, wall_radius, wall_distance, disc_radius,
            disc_distance, normals, risks, end_bounds, end_in_reach, away_normals, away, mean0,
            std0, walk, solved)


@jit(_CLOSE_SIGNATURE)
def wall_speeds(mean0, std0, walk, horizon, risks, low_quantiles, high_quantiles, wall_distance,
                wall_radius, disc_distance, disc_radius, delta):
    """
    Return :func:`line_speeds`' bounds and speeds, and which near shapes are close to ``mu``.

    A shape is close where ``mu`` lies within its grown radius, or where the bound standing
    still of its support line (a disc: its fan's middle tangent) is at least ``delta``.

    Returns
    -------
    still, approach : numpy.ndarray
        As :func:`line_speeds`, shape (C,).
    close : numpy.ndarray
        Per near wall then near disc, shape (n + q,).

    """
    still, approach = line_speeds(mean0, std0, walk, horizon, risks, low_quantiles,
                                  high_quantiles)
    count, discs = wall_distance.size, disc_distance.size
    close = np.empty(count + discs, dtype=np.bool_)
    for wall in range(count):
        close[wall] = (wall_distance[wall] <= wall_radius[wall]
                       or still[wall * PER_WALL] >= delta)
    for disc in range(discs):
        close[count + disc] = (disc_distance[disc] <= disc_radius[disc]
                               or still[count * PER_WALL + disc * FAN + FAN_HALF] >= delta)
    return still, approach, close


@jit(_CANTELLI_SIGNATURE)
def cantelli_bounds(margins, clipped):
    """
    Return Cantelli's bound ``k^2 / (1 + k^2)`` of each margin, and whether all were valid.

    Parameters
    ----------
    margins : numpy.ndarray
        ``k``, shape (K,).
    clipped : bool
        Take ``max(k, 0)`` first (NaN stays NaN).

    Returns
    -------
    bounds : numpy.ndarray
        Shape (K,); 1 from ``k = 1e8`` on (``inf`` included).
    valid : bool
        Whether every ``k`` (after the clip) is at least 0: no NaN, no negative.

    """
    bounds = np.empty(margins.size)
    valid = True
    for index in range(margins.size):
        k = margins[index]
        if clipped and k < 0.0:
            k = 0.0
        if not k >= 0.0:
            valid = False
        if k >= _CERTAIN_K:
            bounds[index] = 1.0
        else:
            bounds[index] = k * k / (1.0 + k * k)
    return bounds, valid


@jit(inline='always')
def _point_segment_distance(point_x, point_y, start_x, start_y, end_x, end_y):
    """Distance of a point from the segment [start, end] (a point where the two are equal)."""
    along_x, along_y = end_x - start_x, end_y - start_y
    length_sq = along_x * along_x + along_y * along_y
    fraction = 0.0
    if length_sq > 0.0:
        fraction = ((point_x - start_x) * along_x + (point_y - start_y) * along_y) / length_sq
        fraction = 0.0 if fraction < 0.0 else (1.0 if fraction > 1.0 else fraction)
    return math.hypot(point_x - (start_x + fraction * along_x),
                      point_y - (start_y + fraction * along_y))


@jit(_INTRUSION_SIGNATURE)
def wall_intrusions(velocities, mean, segments, distance, radius, centres, disc_radius, period):
    """
    Return how far each command moves into a near wall or disc within one period (:mod:`.walls`).

    Per shape ``min(d0, R) - d1`` (0 if nowhere): ``d0`` the distance of ``mu`` from it, ``d1``
    the smallest distance of the path ``mu + t v``, ``t`` in ``[0, period]``, from the segment
    (0 where the two cross) or from the disc's centre. Only shapes within one period's travel
    at the fastest command of their grown radius count; the largest over them.

    Parameters
    ----------
    velocities : numpy.ndarray
        The commands, shape (K, 2).
    mean : numpy.ndarray
        ``mu``, shape (2,).
    segments, distance, radius : numpy.ndarray
        The near walls (n, 2, 2), their distance from ``mu`` and grown radius, (n,) each.
    centres, disc_radius : numpy.ndarray
        The near discs (q, 2) and their grown radius (q,).
    period : float
        How long a command stays in force [s].

    Returns
    -------
    numpy.ndarray
        Shape (K,), at least 0.

    """
    count = velocities.shape[0]
    fastest = 0.0
    for index in range(count):
        fastest = max(fastest, math.hypot(velocities[index, 0], velocities[index, 1]))
    travel = period * fastest
    start_x, start_y = mean[0], mean[1]
    intrusion = np.zeros(count)
    for wall in range(radius.size):
        if not distance[wall] < radius[wall] + travel:
            continue
        a_x, a_y = segments[wall, 0, 0], segments[wall, 0, 1]
        b_x, b_y = segments[wall, 1, 0], segments[wall, 1, 1]
        wall_x, wall_y = b_x - a_x, b_y - a_y
        deepest = min(distance[wall], radius[wall])
        for index in range(count):
            end_x = start_x + period * velocities[index, 0]
            end_y = start_y + period * velocities[index, 1]
            path_x, path_y = end_x - start_x, end_y - start_y
            if ((wall_x * (start_y - a_y) - wall_y * (start_x - a_x))
                    * (wall_x * (end_y - a_y) - wall_y * (end_x - a_x)) < 0.0
                    and (path_x * (a_y - start_y) - path_y * (a_x - start_x))
                    * (path_x * (b_y - start_y) - path_y * (b_x - start_x)) < 0.0):
                separation = 0.0
            else:
                separation = min(
                    _point_segment_distance(start_x, start_y, a_x, a_y, b_x, b_y),
                    _point_segment_distance(end_x, end_y, a_x, a_y, b_x, b_y),
                    _point_segment_distance(a_x, a_y, start_x, start_y, end_x, end_y),
                    _point_segment_distance(b_x, b_y, start_x, start_y, end_x, end_y))
            intrusion[index] = max(intrusion[index], deepest - separation)
    for disc in range(disc_radius.size):
        centre_x, centre_y = centres[disc, 0], centres[disc, 1]
        disc_start = math.hypot(centre_x - start_x, centre_y - start_y)
        if not disc_start < disc_radius[disc] + travel:
            continue
        deepest = min(disc_start, disc_radius[disc])
        for index in range(count):
            end_x = start_x + period * velocities[index, 0]
            end_y = start_y + period * velocities[index, 1]
            intrusion[index] = max(intrusion[index], deepest - _point_segment_distance(
                centre_x, centre_y, start_x, start_y, end_x, end_y))
    return intrusion


@jit(_CONTACT_SIGNATURE)
def contact_times(products, mean, distance, radius, centres, disc_radius, horizon):
    """
    Return how long each command takes to reach the nearest near shape's line, at most tau.

    Per near wall then near disc ``max(d - R, 0) / (-n.v)`` where ``-n.v > 0`` (approaching),
    else never (:func:`.walls.wall_time_to_contact`).

    Parameters
    ----------
    products : numpy.ndarray
        ``n.v`` of every command and shape's normal of moving away, shape (K, n + q).
    mean : numpy.ndarray
        ``mu``, shape (2,).
    distance, radius : numpy.ndarray
        The near walls' distance from ``mu`` and grown radius, (n,) each.
    centres, disc_radius : numpy.ndarray
        The near discs (q, 2) and their grown radius (q,).
    horizon : float
        ``tau`` [s], the cap.

    Returns
    -------
    numpy.ndarray
        Shape (K,).

    """
    walls, shapes = radius.size, products.shape[1]
    clearance = np.empty(shapes)
    for wall in range(walls):
        clearance[wall] = _at_least_zero(distance[wall] - radius[wall])
    for disc in range(shapes - walls):
        clearance[walls + disc] = _at_least_zero(
            math.hypot(centres[disc, 0] - mean[0], centres[disc, 1] - mean[1])
            - disc_radius[disc])
    times = np.empty(products.shape[0])
    for index in range(products.shape[0]):
        soonest = math.inf
        for shape in range(shapes):
            approach = -products[index, shape]
            if approach > 0.0:
                soonest = min(soonest, clearance[shape] / approach)
        times[index] = min(soonest, horizon)
    return times
