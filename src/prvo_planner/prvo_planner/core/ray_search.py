"""
The ray search compiled: feasible speed intervals on every ray (``feasibility.team_ray_gaps``).

One numba function, :func:`team_gaps`, with the helpers of :mod:`.ray_solver`. It is compiled
for one signature when this module is first imported (``feasibility.team_ray_gaps`` imports it
on its first call) and kept in numba's on-disk cache: ``__pycache__`` beside this file, or the
user's cache directory where that cannot be written. ``./run.sh setup`` compiles it once after
installing, so a planner process only loads it (about 0.4 s of CPU; compiling takes 6-7 s).
"""

from numba import types
import numpy as np

from .ray_solver import (
    SEGMENTS,
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
    types.boolean, types.boolean)
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
def _row_roots(coefficients, row, quartic, quadratic_row, roots, test):
    """Write the roots of column ROW of COEFFICIENTS (L, K) into ROOTS[TEST, ROW], NaN-padded."""
    if quadratic_row or not quartic:
        # g's quartic is a quadratic: its mean is linear and its variance quadratic in t.
        roots[test, row, 0], roots[test, row, 1] = quadratic_roots(
            coefficients[0, row], coefficients[1, row], coefficients[2, row])
        roots[test, row, 2] = roots[test, row, 3] = np.nan
    else:
        (roots[test, row, 0], roots[test, row, 1], roots[test, row, 2],
         roots[test, row, 3]) = polynomial_roots(
            coefficients[0, row], coefficients[1, row], coefficients[2, row],
            coefficients[3, row], coefficients[4, row])


@jit(_SIGNATURE)
def team_gaps(means, variances, margins, link_ray, link_enabled, ray_local, preferred,
              conditions, has_receding, has_horizon, taylor, deterministic):
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

    Returns
    -------
    ray : numpy.ndarray
        Ray index of each feasible interval, shape (G,), non-decreasing.
    lower, upper : numpy.ndarray
        Interval ends in ``t``, shape (G,), ``lower < upper``.

    """
    count = means.shape[1]
    links = link_ray.shape[0]
    rays = ray_local.shape[0]
    # The tests: acceptance needs each >= 0 (for the exact method, the quartic and the mean).
    tests = 1
    if deterministic:
        first = means
    elif taylor:
        first = np.empty((3, count))
        row_preferred = np.empty(count)
        for row in range(count):
            row_preferred[row] = preferred[link_ray[row // conditions]]
        taylor_quadratics(means, variances, margins, row_preferred, first)
    else:
        tests = 2
        first = np.empty((5, count))
        for row in range(count):
            constant, linear, square = means[0, row], means[1, row], means[2, row]
            margin_sq = margins[row] * margins[row]
            first[0, row] = constant * constant - margin_sq * variances[0, row]
            first[1, row] = constant * linear * 2.0 - margin_sq * variances[1, row]
            first[2, row] = (constant * square * 2.0 + linear * linear
                             - margin_sq * variances[2, row])
            first[3, row] = linear * square * 2.0 - margin_sq * variances[3, row]
            first[4, row] = square * square - margin_sq * variances[4, row]
    # Per (test, segment, row): how many Bernstein coefficients are >= 0 (all of them: the
    # test is certified >= 0 there; none: < 0).
    counts = np.empty((tests, SEGMENTS, count), dtype=np.uint8)
    segment_certificates(first, counts[0])
    if tests == 2:
        segment_certificates(means, counts[1])
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
    # A segment of a ray is open unless some neighbour rejects all of it: (S, R). (One loop
    # per result: storing both in one loop took ten times as long.)
    accept_pair = np.empty((SEGMENTS, links), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            accept_pair[segment, link] = _some_accepted(
                accept, segment, link * conditions, conditions, has_receding, has_horizon,
                link_enabled[link])
    reject_pair = np.empty((SEGMENTS, links), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            reject_pair[segment, link] = _all_rejected(
                reject, segment, link * conditions, conditions, has_receding, has_horizon,
                link_enabled[link])
    open_segments = np.ones((SEGMENTS, rays), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            if reject_pair[segment, link]:
                open_segments[segment, link_ray[link]] = False
    # Units: (segment, link) on an open segment, not certified accepted there.
    open_unit = np.empty((SEGMENTS, links), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            open_unit[segment, link] = ((not accept_pair[segment, link])
                                        & open_segments[segment, link_ray[link]])
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
                        has_horizon, link_enabled[link]):
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
        test_rows = first if test == 0 else means
        for row in range(count):
            if not needed[test, row]:
                continue
            # Quiet rows: a variance certified positive needs no cuts at the mean's roots.
            if test == 1 and not bernstein_may_vanish(variances, row):
                roots[test, row, :] = np.nan
                continue
            _row_roots(test_rows, row, test_rows.shape[0] == 5,
                       has_receding and row % conditions == 1, roots, test)
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
                        accepted[0, condition] &= _horner_column(means, row, midpoint) >= 0.0
                if not _some_accepted(accepted, 0, 0, conditions, has_receding, has_horizon,
                                      link_enabled[link]):
                    piece_start[rejected] = start
                    piece_end[rejected] = end
                    piece_ray[rejected] = link_ray[link]
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
        shift = 4.0 * ray_local[ray]
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
        shift = 4.0 * ray_local[ray]
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
    return gap_ray[:gaps].copy(), gap_lower[:gaps].copy(), gap_upper[:gaps].copy()
