"""
The ray search compiled: feasible speed intervals on every ray, and what a search is built from.

numba functions, each compiled for one signature when this module is first imported (the
planner imports it on its first plan) and kept in numba's on-disk cache: ``__pycache__`` beside
this file, or the user's cache directory where that cannot be written. ``./run.sh setup``
compiles them once after installing, so a planner process only loads them.

* :func:`relative_gaussians`, the neighbours of a plan as relative Gaussians
  (``encounter.build_encounter``);
* :func:`ray_links`, every neighbour's bivariate polynomials restricted to its robot's rays,
  laid out as the search's links (the planner's ``_ray_search``);
* :func:`team_gaps`, the feasible intervals on every ray (``feasibility.team_ray_gaps``), with
  the helpers of :mod:`.ray_solver`;
* :func:`link_margins` and :func:`achieved_margins`, the ``k`` met at chosen points, from the
  ray polynomials or from the conditions' moments (``feasibility.achieved_margins``).
"""

import math

from numba import types
import numpy as np

from .ray_solver import (
    READ_ONLY_CUBE,
    READ_ONLY_FLAGS,
    READ_ONLY_INDICES,
    READ_ONLY_ROWS,
    READ_ONLY_VECTOR,
    SEGMENTS,
    _fma,
    _maximum,
    _minimum,
    bernstein_may_vanish,
    jit,
    polynomial_roots,
    quadratic_roots,
    segment_certificates,
    taylor_quadratics,
)

_FLOATS = types.float64[:, ::1]
_SIGNATURE = types.Tuple((types.int64[::1], types.float64[::1], types.float64[::1]))(
    _FLOATS, _FLOATS, types.float64[::1], types.int64[::1], types.boolean[::1],
    types.int64[::1], types.float64[::1], types.int64, types.boolean, types.boolean,
    types.boolean, types.boolean, types.boolean[::1])
# Roots of one test's row: four of a quartic, two of a quadratic.
_ROOTS = 4


@jit(inline='always')
def _all_rejected(reject, segment, base, conditions, has_receding, has_horizon, enabled):
    """Whether every alternative ``f or g or (h1 and h2) or h3`` is rejected on SEGMENT."""
    result = reject[segment, base]
    if has_receding:
        result &= (not enabled) | reject[segment, base + 1]
    if has_horizon:
        first = base + conditions - 3
        result &= ((reject[segment, first] | reject[segment, first + 1])
                   & reject[segment, first + 2])
    return result


@jit(inline='always')
def _some_accepted(accept, segment, base, conditions, has_receding, has_horizon, enabled):
    """Whether ``f or g or (h1 and h2) or h3`` holds, from ACCEPT flags (segment, row)."""
    result = accept[segment, base]
    if has_receding:
        result |= enabled & accept[segment, base + 1]
    if has_horizon:
        first = base + conditions - 3
        result |= ((accept[segment, first] & accept[segment, first + 1])
                   | accept[segment, first + 2])
    return result


@jit(inline='always')
def _relevant(reject, segment, base, condition, conditions, has_receding, has_horizon,
              enabled):
    """
    Whether a condition's acceptance can change its pair's on a segment.

    A disabled ``g`` cannot, nor can ``h1`` (``h2``) when ``h2`` (``h1``) is rejected on the
    whole segment; their roots need not bound pieces.
    """
    if has_horizon and condition == conditions - 3:
        return not reject[segment, base + conditions - 2]
    if has_horizon and condition == conditions - 2:
        return not reject[segment, base + conditions - 3]
    if has_receding and condition == 1:
        return enabled
    return True


@jit()
def _horner_column(coefficients, row, t):
    """Evaluate column ROW of coefficient-major COEFFICIENTS (L, K) at T by Horner's rule."""
    length = coefficients.shape[0]
    value = coefficients[length - 1, row]
    for power in range(length - 2, -1, -1):
        value = value * t + coefficients[power, row]
    return value


@jit()
def _row_roots(coefficients, column, quartic, quadratic_row, roots, test, row):
    """Write the roots of column COLUMN of COEFFICIENTS (L, K) to ROOTS[TEST, ROW], NaN-padded."""
    if quadratic_row or not quartic:
        # g's quartic is a quadratic: its mean is linear and its variance quadratic in t.
        roots[test, row, 0], roots[test, row, 1] = quadratic_roots(
            coefficients[0, column], coefficients[1, column], coefficients[2, column])
        roots[test, row, 2] = roots[test, row, 3] = np.nan
    else:
        (roots[test, row, 0], roots[test, row, 1], roots[test, row, 2],
         roots[test, row, 3]) = polynomial_roots(
            coefficients[0, column], coefficients[1, column], coefficients[2, column],
            coefficients[3, column], coefficients[4, column])


@jit()
def _robot_gaps(means, variances, margins, link_ray, link_enabled, ray_local, preferred,
                conditions, has_receding, has_horizon, taylor, deterministic, first_row, count,
                first_link, links, first_ray, rays):
    """
    :func:`team_gaps` of one robot: COUNT rows, LINKS links and RAYS rays of the call's arrays.

    The robot's are the call's from FIRST_ROW, FIRST_LINK and FIRST_RAY on; the working arrays
    are the robot's alone, indexed from 0.
    """
    # The tests: acceptance needs each >= 0 (for the exact method, the quartic and the mean).
    tests = 1
    if deterministic:
        first = np.ascontiguousarray(means[:, first_row:first_row + count])
    elif taylor:
        first = np.empty((3, count))
        row_preferred = np.empty(count)
        for row in range(count):
            row_preferred[row] = preferred[link_ray[first_link + row // conditions]]
        taylor_quadratics(np.ascontiguousarray(means[:, first_row:first_row + count]),
                          np.ascontiguousarray(variances[:, first_row:first_row + count]),
                          margins[first_row:first_row + count], row_preferred, first)
    else:
        tests = 2
        first = np.empty((5, count))
        for row in range(count):
            column = first_row + row
            constant, linear, square = means[0, column], means[1, column], means[2, column]
            margin_sq = margins[column] * margins[column]
            first[0, row] = constant * constant - margin_sq * variances[0, column]
            first[1, row] = constant * linear * 2.0 - margin_sq * variances[1, column]
            first[2, row] = (constant * square * 2.0 + linear * linear
                             - margin_sq * variances[2, column])
            first[3, row] = linear * square * 2.0 - margin_sq * variances[3, column]
            first[4, row] = square * square - margin_sq * variances[4, column]
    # Per (test, segment, row): how many Bernstein coefficients are >= 0 (all of them: the
    # test is certified >= 0 there; none: < 0).
    counts = np.empty((tests, SEGMENTS, count), dtype=np.uint8)
    segment_certificates(first, 0, counts[0])
    if tests == 2:
        segment_certificates(means, first_row, counts[1])
    lengths = (first.shape[0], 3)
    # Per (segment, row): every test certified >= 0, some test certified < 0.
    accept = np.empty((SEGMENTS, count), dtype=np.bool_)
    reject = np.empty((SEGMENTS, count), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for row in range(count):
            accept[segment, row] = counts[0, segment, row] == lengths[0]
            if tests == 2:
                accept[segment, row] &= counts[1, segment, row] == lengths[1]
    for segment in range(SEGMENTS):
        for row in range(count):
            reject[segment, row] = counts[0, segment, row] == 0
            if tests == 2:
                reject[segment, row] |= counts[1, segment, row] == 0
    # A segment of a ray is open unless some neighbour rejects all of it: (S, R).
    open_segments = np.ones((SEGMENTS, rays), dtype=np.bool_)
    for link in range(links):
        base, enabled = link * conditions, link_enabled[first_link + link]
        for segment in range(SEGMENTS):
            if _all_rejected(reject, segment, base, conditions, has_receding, has_horizon,
                             enabled):
                open_segments[segment, link_ray[first_link + link] - first_ray] = False
    # Units: (segment, link) on an open segment, not certified accepted there.
    open_unit = np.empty((SEGMENTS, links), dtype=np.bool_)
    for link in range(links):
        base, enabled = link * conditions, link_enabled[first_link + link]
        ray = link_ray[first_link + link] - first_ray
        for segment in range(SEGMENTS):
            open_unit[segment, link] = open_segments[segment, ray] and not _some_accepted(
                accept, segment, base, conditions, has_receding, has_horizon, enabled)
    # Only a condition undecided on a segment can split it, and only where its own test is;
    # each test's undecided rows need their roots.
    undecided = np.zeros((tests, SEGMENTS, count), dtype=np.bool_)
    needed = np.zeros((tests, count), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            if not open_unit[segment, link]:
                continue
            base = link * conditions
            for condition in range(conditions):
                row = base + condition
                if accept[segment, row] or reject[segment, row] or not _relevant(
                        reject, segment, base, condition, conditions, has_receding,
                        has_horizon, link_enabled[first_link + link]):
                    continue
                for test in range(tests):
                    signs = counts[test, segment, row]
                    if signs != 0 and signs != lengths[test]:
                        undecided[test, segment, row] = True
                        needed[test, row] = True
    # Per (test, row), written where needed (NaN for a quiet row).
    roots = np.empty((tests, count, _ROOTS))
    inside = 0
    for test in range(tests):
        test_rows, test_first = (first, 0) if test == 0 else (means, first_row)
        for row in range(count):
            if not needed[test, row]:
                continue
            # Quiet rows: a variance certified positive needs no cuts at the mean's roots.
            if test == 1 and not bernstein_may_vanish(variances, first_row + row):
                roots[test, row, :] = np.nan
                continue
            _row_roots(test_rows, test_first + row, test_rows.shape[0] == 5,
                       has_receding and row % conditions == 1, roots, test, row)
            for index in range(_ROOTS):
                value = roots[test, row, index]
                if value > 0.0 and value < 1.0:
                    inside += 1
    # Every open unit cut at its segment's ends and the roots inside it; each piece accepted
    # or not by its midpoint. The rejected pieces are kept: their ends and link.
    units = 0
    for segment in range(SEGMENTS):
        for link in range(links):
            units += open_unit[segment, link]
    piece_start = np.empty(units + inside)
    piece_end = np.empty(units + inside)
    piece_ray = np.empty(units + inside, dtype=np.int64)
    rejected = 0
    cuts = np.empty(2 + tests * conditions * _ROOTS)
    accepted = np.empty((1, conditions), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            if not open_unit[segment, link]:
                continue
            base = link * conditions
            cut_count = 1
            cuts[0] = segment / SEGMENTS
            for test in range(tests):
                for condition in range(conditions):
                    row = base + condition
                    if not undecided[test, segment, row]:
                        continue
                    for index in range(_ROOTS):
                        value = roots[test, row, index]
                        if (value > 0.0 and value < 1.0
                                and min(int(value * SEGMENTS), SEGMENTS - 1) == segment):
                            # Insertion into the sorted roots.
                            position = cut_count
                            while position > 1 and cuts[position - 1] > value:
                                cuts[position] = cuts[position - 1]
                                position -= 1
                            cuts[position] = value
                            cut_count += 1
            cuts[cut_count] = (segment + 1) / SEGMENTS
            for piece in range(cut_count):
                start, end = cuts[piece], cuts[piece + 1]
                midpoint = 0.5 * (start + end)
                for condition in range(conditions):
                    row = base + condition
                    accepted[0, condition] = _horner_column(first, row, midpoint) >= 0.0
                    if tests == 2:
                        accepted[0, condition] &= _horner_column(
                            means, first_row + row, midpoint) >= 0.0
                if not _some_accepted(accepted, 0, 0, conditions, has_receding, has_horizon,
                                      link_enabled[first_link + link]):
                    piece_start[rejected] = start
                    piece_end[rejected] = end
                    piece_ray[rejected] = link_ray[first_link + link] - first_ray
                    rejected += 1
    # Per open ray, its rejected pieces, its closed segments and two sentinels (rejecting
    # t < 0 and t > 1), shifted by 4 per direction of its robot as the intervals were when
    # numpy swept every ray of a robot in one sort, so that the ends are the same numbers.
    open_rays = np.zeros(rays, dtype=np.bool_)
    entry_count = np.zeros(rays + 1, dtype=np.int64)
    for ray in range(rays):
        for segment in range(SEGMENTS):
            open_rays[ray] |= open_segments[segment, ray]
        if open_rays[ray]:
            entry_count[ray + 1] = 2
            for segment in range(SEGMENTS):
                entry_count[ray + 1] += not open_segments[segment, ray]
    for piece in range(rejected):
        entry_count[piece_ray[piece] + 1] += 1
    entry_first = np.cumsum(entry_count)
    entries = entry_first[rays]
    starts = np.empty(entries)
    ends = np.empty(entries)
    filled = entry_first[:rays].copy()
    for piece in range(rejected):
        ray = piece_ray[piece]
        shift = 4.0 * ray_local[first_ray + ray]
        starts[filled[ray]] = piece_start[piece] + shift
        ends[filled[ray]] = piece_end[piece] + shift
        filled[ray] += 1
    gap_ray = np.empty(entries, dtype=np.int64)
    gap_lower = np.empty(entries)
    gap_upper = np.empty(entries)
    gaps = 0
    for ray in range(rays):
        if not open_rays[ray]:
            continue
        shift = 4.0 * ray_local[first_ray + ray]
        for segment in range(SEGMENTS):
            if not open_segments[segment, ray]:
                starts[filled[ray]] = segment / SEGMENTS + shift
                ends[filled[ray]] = (segment + 1) / SEGMENTS + shift
                filled[ray] += 1
        starts[filled[ray]] = -1.0 + shift
        ends[filled[ray]] = 0.0 + shift
        starts[filled[ray] + 1] = 1.0 + shift
        ends[filled[ray] + 1] = 3.0 + shift
        first_entry = entry_first[ray]
        ray_starts = starts[first_entry:entry_first[ray + 1]]
        ray_ends = ends[first_entry:entry_first[ray + 1]]
        order = np.argsort(ray_starts, kind='mergesort')
        # The running end of the rejected set; a gap where the next start lies beyond it.
        reach = ray_ends[order[0]]
        for index in range(1, order.shape[0]):
            start = ray_starts[order[index]]
            if start > reach:
                gap_ray[gaps] = ray
                gap_lower[gaps] = reach - shift
                gap_upper[gaps] = start - shift
                gaps += 1
            reach = max(reach, ray_ends[order[index]])
    return gap_ray[:gaps] + first_ray, gap_lower[:gaps], gap_upper[:gaps]


@jit(_SIGNATURE)
def team_gaps(means, variances, margins, link_ray, link_enabled, ray_local, preferred,
              conditions, has_receding, has_horizon, taylor, deterministic, searched):
    """
    Feasible speed intervals on every ray: the intersection over neighbours of accepted sets.

    Rays are split into ``SEGMENTS`` equal segments of ``t``. A segment that some neighbour
    rejects entirely (a Bernstein certificate) is closed; on every other segment, each
    (neighbour, direction) link whose acceptance is not certified there is cut at the roots of
    its tests that fall in the segment; each piece is accepted or not by its midpoint, and the
    rejected pieces and closed segments of each ray are swept in order. Every value of a ray
    is computed by the same operations whatever the other rays in the call, so a robot's
    intervals do not depend on which robots are planned with it.

    For the exact method ``mean - k sigma >= 0`` iff ``mean >= 0`` and ``mean^2 - k^2 var >= 0``
    (the quartic). Where the variance is certified positive on the ray, the surrogate changes
    only where ``mean = k sigma``, a root of the quartic, so the mean's roots bound pieces only
    where the variance may vanish (there the quartic has a double root at the mean's root,
    which closed-form roots resolve poorly).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition polynomials of the K = P C rows (link-major), coefficient-major: shapes
        (3, K) and (5, K).
    margins : numpy.ndarray
        ``k`` per row, shape (K,).
    link_ray, link_enabled : numpy.ndarray
        Ray of each link, and whether ``g`` counts for it, shape (P,).
    ray_local : numpy.ndarray
        Index of each ray among its robot's directions, shape (R,); a robot's rays are
        consecutive.
    preferred : numpy.ndarray
        Preferred ``t`` per ray, shape (R,).
    conditions : int
        Condition columns C: ``f``, then ``g`` if ``has_receding``, then ``h1, h2, h3`` if
        ``has_horizon``.
    has_receding, has_horizon : bool
        The layout.
    taylor : bool
        The Taylor method (a quadratic surrogate) instead of the exact one.
    deterministic : bool
        All variances are zero (the mean alone decides).
    searched : numpy.ndarray
        Per robot (a robot's rays begin where ``ray_local`` is 0), whether its rays are
        searched; the others have no intervals. Shape (B,).

    Returns
    -------
    ray : numpy.ndarray
        Ray index of each feasible interval, shape (G,), non-decreasing.
    lower, upper : numpy.ndarray
        Interval ends in ``t``, shape (G,), ``lower < upper``.

    """
    links = link_ray.shape[0]
    rays = ray_local.shape[0]
    # Robot by robot: a robot's links and rays are consecutive, and its rows' working arrays
    # then stay in the processor's cache (a crowd's call is some 750,000 rows; whole, the
    # search streamed each phase's arrays through memory, 1.45x slower: docs/results.md, 5.22).
    ray_lower = np.empty(rays + 1, dtype=np.int64)
    link_lower = np.empty(rays + 1, dtype=np.int64)
    robots = 0
    link = 0
    for ray in range(rays):
        if ray_local[ray] == 0:
            while link < links and link_ray[link] < ray:
                link += 1
            ray_lower[robots], link_lower[robots] = ray, link
            robots += 1
    ray_lower[robots], link_lower[robots] = rays, links
    if searched.shape[0] != robots:
        raise ValueError('team_gaps: searched must hold one flag per robot')
    pieces = []
    total = 0
    for robot in range(robots):
        if not searched[robot]:
            continue
        piece = _robot_gaps(
            means, variances, margins, link_ray, link_enabled, ray_local, preferred, conditions,
            has_receding, has_horizon, taylor, deterministic, link_lower[robot] * conditions,
            (link_lower[robot + 1] - link_lower[robot]) * conditions, link_lower[robot],
            link_lower[robot + 1] - link_lower[robot], ray_lower[robot],
            ray_lower[robot + 1] - ray_lower[robot])
        total += piece[0].shape[0]
        pieces.append(piece)
    gap_ray = np.empty(total, dtype=np.int64)
    gap_lower = np.empty(total)
    gap_upper = np.empty(total)
    filled = 0
    for piece in pieces:
        size = piece[0].shape[0]
        gap_ray[filled:filled + size] = piece[0]
        gap_lower[filled:filled + size] = piece[1]
        gap_upper[filled:filled + size] = piece[2]
        filled += size
    return gap_ray, gap_lower, gap_upper


# The monomials x^i y^j of a bivariate quartic, grouped by degree (:mod:`.moments`' order):
# their exponents (the quadratics' six are the first six).
_EXPONENT_X = np.array([0, 1, 0, 2, 1, 0, 3, 2, 1, 0, 4, 3, 2, 1, 0])
_EXPONENT_Y = np.array([0, 0, 1, 0, 1, 2, 0, 1, 2, 3, 0, 1, 2, 3, 4])
@jit(inline='always')
def _restricted(mean_fit, variance_fit, pair, condition, e, ray_start, rays, first_link,
                v, means, variances):
    """
    Write one neighbour's condition restricted to RAYS rays into MEANS and VARIANCES.

    E holds every ray's monomials ``e_x^i e_y^j``, (R, 15).
    The coefficient of ``t^l`` is the monomials of degree ``l`` in order, each times its
    coefficient: a product, then fused multiply-adds. V (15,) is scratch.
    """
    m0, m1, m2, m3, m4, m5 = (mean_fit[pair, 0, condition], mean_fit[pair, 1, condition],
                              mean_fit[pair, 2, condition], mean_fit[pair, 3, condition],
                              mean_fit[pair, 4, condition], mean_fit[pair, 5, condition])
    for index in range(15):
        v[index] = variance_fit[pair, index, condition]
    for ray in range(rays):
        r = ray_start + ray
        link = first_link + ray
        means[0, link, condition] = m0 * e[r, 0]
        means[1, link, condition] = _fma(m2, e[r, 2], m1 * e[r, 1])
        means[2, link, condition] = _fma(m5, e[r, 5], _fma(m4, e[r, 4], m3 * e[r, 3]))
        variances[0, link, condition] = v[0] * e[r, 0]
        variances[1, link, condition] = _fma(v[2], e[r, 2], v[1] * e[r, 1])
        variances[2, link, condition] = _fma(v[5], e[r, 5], _fma(v[4], e[r, 4],
                                                                 v[3] * e[r, 3]))
        variances[3, link, condition] = _fma(v[9], e[r, 9], _fma(v[8], e[r, 8], _fma(
            v[7], e[r, 7], v[6] * e[r, 6])))
        variances[4, link, condition] = _fma(v[14], e[r, 14], _fma(v[13], e[r, 13], _fma(
            v[12], e[r, 12], _fma(v[11], e[r, 11], v[10] * e[r, 10]))))


_INTS = types.int64[::1]
_LINKS_SIGNATURE = types.Tuple((
    types.float64[:, :, ::1], types.float64[:, :, ::1], _FLOATS, _INTS, _INTS, types.boolean[::1],
    types.int64[:, ::1], _INTS, _INTS, _INTS))(
    READ_ONLY_CUBE, READ_ONLY_CUBE, READ_ONLY_ROWS, READ_ONLY_INDICES, READ_ONLY_INDICES,
    READ_ONLY_ROWS, READ_ONLY_FLAGS)


@jit(_LINKS_SIGNATURE)
def ray_links(mean_fit, variance_fit, directions, pair_counts, ray_counts, robot_margins,
              enabled):
    """
    Restrict every neighbour's bivariate polynomials to its robot's rays: the links of a search.

    Along the ray ``v_c = t v_max e`` the monomial ``(v_x / v_max)^i (v_y / v_max)^j`` is
    ``t^(i+j) e_x^i e_y^j``, so the coefficient of ``t^l`` is the sum over the monomials of
    degree ``l`` of their coefficients times ``e_x^i e_y^j``: summed in the monomials' order by
    fused multiply-adds, as OpenBLAS's matrix product with the (15, 5 M) map of every ray did,
    with ``e^i`` as ``pow``.

    Parameters
    ----------
    mean_fit, variance_fit : numpy.ndarray
        Bivariate coefficients per neighbour of the robots, robot after robot, shapes (N, 6, C)
        and (N, 15, C) (:func:`.moments.bivariate_polynomials`, its last two axes swapped).
    directions : numpy.ndarray
        Unit directions of every robot's rays, robot after robot, shape (R, 2).
    pair_counts, ray_counts : numpy.ndarray
        Neighbours and rays per robot, shape (B,).
    robot_margins : numpy.ndarray
        ``k`` per robot and condition column, shape (B, C).
    enabled : numpy.ndarray
        Whether ``g`` counts, per neighbour, shape (N,).

    Returns
    -------
    means, variances : numpy.ndarray
        Coefficients in ``t`` of every link (a robot's in (neighbour, direction) order, robot
        after robot) and condition, coefficient-major: shapes (3, P, C) and (5, P, C).
    margins : numpy.ndarray
        ``k`` per link and condition column, shape (P, C).
    link_ray, link_pair : numpy.ndarray
        Ray and neighbour of each link, shape (P,).
    link_enabled : numpy.ndarray
        Whether ``g`` counts for each link, shape (P,).
    starts : numpy.ndarray
        The first neighbour, ray and link of each robot, shape (3, B).
    ray_local, ray_robot : numpy.ndarray
        Each ray's index among its robot's, and its robot, shape (R,).
    pair_robot : numpy.ndarray
        Each neighbour's robot, shape (N,).

    """
    robots = pair_counts.shape[0]
    conditions = mean_fit.shape[2]
    starts = np.zeros((3, robots), dtype=np.int64)
    links = 0
    for robot in range(robots):
        if robot > 0:
            starts[0, robot] = starts[0, robot - 1] + pair_counts[robot - 1]
            starts[1, robot] = starts[1, robot - 1] + ray_counts[robot - 1]
            starts[2, robot] = starts[2, robot - 1] + pair_counts[robot - 1] * ray_counts[
                robot - 1]
        links += pair_counts[robot] * ray_counts[robot]
    means = np.empty((3, links, conditions))
    variances = np.empty((5, links, conditions))
    margins = np.empty((links, conditions))
    link_ray = np.empty(links, dtype=np.int64)
    link_pair = np.empty(links, dtype=np.int64)
    link_enabled = np.empty(links, dtype=np.bool_)
    ray_local = np.empty(directions.shape[0], dtype=np.int64)
    ray_robot = np.empty(directions.shape[0], dtype=np.int64)
    pair_robot = np.empty(mean_fit.shape[0], dtype=np.int64)
    # Every ray's monomials e_x^i e_y^j, (R, 15).
    monomials = np.empty((directions.shape[0], 15))
    scratch = np.empty(15)
    powers = np.empty((2, 5))
    for ray in range(directions.shape[0]):
        for axis in range(2):
            powers[axis, 0], powers[axis, 1] = 1.0, directions[ray, axis]
            for exponent in range(2, 5):
                powers[axis, exponent] = math.pow(directions[ray, axis], float(exponent))
        for index in range(15):
            monomials[ray, index] = powers[0, _EXPONENT_X[index]] * powers[1, _EXPONENT_Y[index]]
    for robot in range(robots):
        pair_start, ray_start, rays = starts[0, robot], starts[1, robot], ray_counts[robot]
        for ray in range(rays):
            ray_local[ray_start + ray] = ray
            ray_robot[ray_start + ray] = robot
        link = starts[2, robot]
        for pair in range(pair_start, pair_start + pair_counts[robot]):
            pair_robot[pair] = robot
            for ray in range(ray_start, ray_start + rays):
                link_ray[link] = ray
                link_pair[link] = pair
                link_enabled[link] = enabled[pair]
                for condition in range(conditions):
                    margins[link, condition] = robot_margins[robot, condition]
                link += 1
        for pair in range(pair_start, pair_start + pair_counts[robot]):
            first_link = starts[2, robot] + (pair - pair_start) * rays
            for condition in range(conditions):
                _restricted(mean_fit, variance_fit, pair, condition, monomials, ray_start, rays,
                            first_link, scratch, means, variances)
    return (means, variances, margins, link_ray, link_pair, link_enabled, starts, ray_local,
            ray_robot, pair_robot)


@jit(inline='always')
def _margin(mean, variance):
    """Return the ``k`` a condition meets: ``mean / sigma``, ``+-inf`` at ``sigma = 0``."""
    margin = mean / math.sqrt(_maximum(variance, 0.0))
    return np.inf if margin != margin else margin


@jit(inline='always')
def _combined_margin(margins, conditions, has_receding, has_horizon, enabled):
    """
    Return the largest ``k`` met by an accepted alternative, from each condition's MARGINS.

    The pair ``h1 and h2`` meets ``k' = min(k_h1, k_h2)``, reported as the pairwise ``k`` with
    that ``k'``: ``sqrt((k'^2 - 1) / 2)``, and ``k' - 1 < 0`` below ``k' = 1``.
    """
    result = margins[0]
    if has_receding:
        result = _maximum(result, margins[1] if enabled else -np.inf)
    if has_horizon:
        joint = _minimum(margins[conditions - 3], margins[conditions - 2])
        pairwise = joint * joint
        pairwise -= 1.0
        pairwise *= 0.5
        pairwise = math.sqrt(pairwise) if joint >= 1.0 else joint - 1.0
        result = _maximum(_maximum(result, pairwise), margins[conditions - 1])
    return result


_MARGINS_SIGNATURE = types.float64[::1](READ_ONLY_ROWS, READ_ONLY_ROWS, READ_ONLY_FLAGS,
                                         types.boolean, types.boolean)
_LINK_MARGINS_SIGNATURE = types.float64[::1](
    READ_ONLY_CUBE, READ_ONLY_CUBE, READ_ONLY_INDICES, READ_ONLY_VECTOR, READ_ONLY_FLAGS,
    types.boolean, types.boolean)


@jit(_MARGINS_SIGNATURE)
def achieved_margins(means, variances, enabled, has_receding, has_horizon):
    """
    Return the ``k`` met at given points (docs/method.md, section 7: no accepted velocity).

    Per condition ``mean / sigma`` (``+-inf`` at ``sigma = 0``, and any ``k`` for a zero mean
    known exactly); the largest over the accepted alternatives (:func:`_combined_margin`).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Condition values at the points, shape (K, C).
    enabled : numpy.ndarray
        Whether ``g`` counts at each point, shape (K,).
    has_receding, has_horizon : bool
        The layout: ``f``, then ``g`` if ``has_receding``, then ``h1, h2, h3``.

    Returns
    -------
    numpy.ndarray
        Shape (K,).

    """
    count, conditions = means.shape
    result = np.empty(count)
    margins = np.empty(conditions)
    for row in range(count):
        for condition in range(conditions):
            margins[condition] = _margin(means[row, condition], variances[row, condition])
        result[row] = _combined_margin(margins, conditions, has_receding, has_horizon,
                                       enabled[row])
    return result


@jit(_LINK_MARGINS_SIGNATURE)
def link_margins(means, variances, links, t, enabled, has_receding, has_horizon):
    """
    Return the ``k`` met on given links at given ``t``, from their ray polynomials.

    Parameters
    ----------
    means, variances : numpy.ndarray
        Coefficients in ``t`` of every link and condition, coefficient-major: shapes (3, P, C)
        and (5, P, C) (:func:`ray_links`).
    links : numpy.ndarray
        The links, shape (K,).
    t : numpy.ndarray
        Where on each link's ray, shape (K,).
    enabled : numpy.ndarray
        Whether ``g`` counts on each link, shape (K,).
    has_receding, has_horizon : bool
        The layout.

    Returns
    -------
    numpy.ndarray
        Shape (K,), as :func:`achieved_margins` of the polynomials' values by Horner's rule.

    """
    conditions = means.shape[2]
    result = np.empty(links.shape[0])
    margins = np.empty(conditions)
    for index in range(links.shape[0]):
        link, point = links[index], t[index]
        for condition in range(conditions):
            mean = means[2, link, condition]
            for power in range(1, -1, -1):
                mean = mean * point + means[power, link, condition]
            variance = variances[4, link, condition]
            for power in range(3, -1, -1):
                variance = variance * point + variances[power, link, condition]
            margins[condition] = _margin(mean, variance)
        result[index] = _combined_margin(margins, conditions, has_receding, has_horizon,
                                         enabled[index])
    return result


_ENCOUNTER_SIGNATURE = types.Tuple((_FLOATS, types.float64[:, :, ::1], types.float64[::1],
                                    types.float64[::1], types.boolean[::1], types.int64))(
    READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_ROWS, types.float64, READ_ONLY_ROWS,
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_ROWS,
    types.float64, types.float64, types.float64, types.float64, types.float64)


@jit(_ENCOUNTER_SIGNATURE)
def relative_gaussians(ego_position, ego_velocity, ego_cov, ego_radius, positions, velocities,
                       covariances, radii, shares, actuation_cov, neighbor_distance, guard_time,
                       max_speed, time_horizon, safety_margin):
    """
    Return the neighbours within reach as relative Gaussians (:func:`.encounter.build_encounter`).

    A neighbour is kept if the gap between the mean disks is at most ``neighbor_distance``; one
    that takes a share of the avoidance and could touch the ego within ``guard_time`` has a
    second row after all the others, of share 0, its velocity terms scaled by ``guard_time /
    time_horizon`` where that is below 1. With ``rho = 1 - share``, ``lead = 1 / rho`` and the
    ego's weight ``(1 - rho) / rho``, the mean of ``z = (r, w)`` at zero command is ``(p_ego -
    p_j, -weight v_ego - v_j)`` and its covariance sums the ego's, the neighbour's and the
    actuation noise's (``lead^2 S_a``) blocks.

    Parameters
    ----------
    ego_position, ego_velocity : numpy.ndarray
        The ego's mean position and velocity, shape (2,).
    ego_cov : numpy.ndarray
        The ego's covariance of (position, velocity), shape (4, 4).
    ego_radius : float
        The ego's radius.
    positions, velocities : numpy.ndarray
        The neighbours' means, shape (n, 2).
    covariances : numpy.ndarray
        The neighbours' covariances, shape (n, 4, 4).
    radii, shares : numpy.ndarray
        The neighbours' radii and avoidance shares, shape (n,).
    actuation_cov : numpy.ndarray
        The actuation noise's covariance, shape (2, 2).
    neighbor_distance, guard_time, max_speed, time_horizon, safety_margin : float
        As in :class:`.config.PlannerConfig`.

    Returns
    -------
    origin, cov, lead, combined_radius, overlapping : numpy.ndarray
        Shapes (N, 4), (N, 4, 4), (N,), (N,) and (N,): the kept neighbours in order, then their
        guard rows.
    guarded : int
        How many guard rows there are.

    """
    count = positions.shape[0]
    distance = np.empty(count)
    gap = np.empty(count)
    kept = np.empty(count, dtype=np.int64)
    guard = np.empty(count, dtype=np.int64)
    selected = guarded = 0
    for neighbour in range(count):
        distance[neighbour] = math.hypot(ego_position[0] - positions[neighbour, 0],
                                         ego_position[1] - positions[neighbour, 1])
        gap[neighbour] = distance[neighbour] - ego_radius - radii[neighbour]
        if gap[neighbour] <= neighbor_distance:
            kept[selected] = neighbour
            selected += 1
    if guard_time > 0.0:
        for index in range(selected):
            neighbour = kept[index]
            # Within reach of the guard time, each going at most as fast as it may (the ego)
            # or as it goes (the neighbour).
            reach = guard_time * (max_speed + math.hypot(velocities[neighbour, 0],
                                                         velocities[neighbour, 1]))
            if gap[neighbour] < reach and shares[neighbour] > 0.0:
                guard[guarded] = neighbour
                guarded += 1
    rows = selected + guarded
    origin = np.empty((rows, 4))
    cov = np.empty((rows, 4, 4))
    lead = np.empty(rows)
    combined_radius = np.empty(rows)
    overlapping = np.empty(rows, dtype=np.bool_)
    scale = guard_time / time_horizon
    scaled = guarded > 0 and guard_time < time_horizon
    for row in range(rows):
        neighbour = kept[row] if row < selected else guard[row - selected]
        share = shares[neighbour] if row < selected else 0.0
        rho = 1.0 - share
        lead[row] = 1.0 / rho
        weight = (1.0 - rho) / rho
        lead_sq, weight_sq = lead[row] * lead[row], weight * weight
        for i in range(2):
            for j in range(2):
                cov[row, i, j] = ego_cov[i, j] + covariances[neighbour, i, j]
                cov[row, 2 + i, 2 + j] = (lead_sq * actuation_cov[i, j]
                                          + weight_sq * ego_cov[2 + i, 2 + j]
                                          + covariances[neighbour, 2 + i, 2 + j])
                cross = -weight * ego_cov[i, 2 + j] + covariances[neighbour, i, 2 + j]
                cov[row, i, 2 + j] = cross
                cov[row, 2 + j, i] = cross
            origin[row, i] = ego_position[i] - positions[neighbour, i]
            origin[row, 2 + i] = -weight * ego_velocity[i] - velocities[neighbour, i]
        if scaled and row >= selected:
            # Contact within the guard time along w is contact within the horizon along w
            # scaled by guard_time / time_horizon.
            for i in range(2):
                origin[row, 2 + i] *= scale
                for j in range(2):
                    cov[row, 2 + i, 2 + j] *= math.pow(scale, 2.0)
                    cov[row, i, 2 + j] *= scale
                    cov[row, 2 + i, j] *= scale
            lead[row] *= scale
        combined_radius[row] = ego_radius + radii[neighbour] + safety_margin
        overlapping[row] = distance[neighbour] < combined_radius[row]
    return origin, cov, lead, combined_radius, overlapping, guarded
