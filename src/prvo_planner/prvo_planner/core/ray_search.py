"""
The ray search compiled: feasible speed intervals on every ray (``feasibility.team_ray_gaps``).

One numba function, :func:`team_gaps`, with the helpers of :mod:`.ray_solver`. It is compiled
for one signature when this module is first imported (``feasibility.team_ray_gaps`` imports it
on its first call) and kept in numba's on-disk cache: ``__pycache__`` beside this file, or the
user's cache directory where that cannot be written. ``./run.sh setup`` compiles it once after
installing, so a planner process only loads it (about half a second; compiling takes 10-15 s).
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


@jit()
def _all_rejected(reject, base, conditions, has_receding, has_horizon, enabled):
    """Whether every accepted alternative ``f or g or (h1 and h2) or h3`` is rejected."""
    if not reject[base]:
        return False
    if has_receding and enabled and not reject[base + 1]:
        return False
    if has_horizon:
        if not (reject[base + conditions - 3] or reject[base + conditions - 2]):
            return False
        if not reject[base + conditions - 1]:
            return False
    return True


@jit()
def _some_accepted(accept, base, conditions, has_receding, has_horizon, enabled):
    """Whether ``f or g or (h1 and h2) or h3`` holds, from per-condition ACCEPT flags."""
    if accept[base]:
        return True
    if has_receding and enabled and accept[base + 1]:
        return True
    if has_horizon:
        if accept[base + conditions - 3] and accept[base + conditions - 2]:
            return True
        if accept[base + conditions - 1]:
            return True
    return False


@jit()
def _relevant(reject, base, condition, conditions, has_receding, has_horizon, enabled):
    """
    Whether a condition's acceptance can change its pair's on a segment.

    A disabled ``g`` cannot, nor can ``h1`` (``h2``) when ``h2`` (``h1``) is rejected on the
    whole segment; their roots need not bound pieces.
    """
    if has_horizon and condition == conditions - 3:
        return not reject[base + conditions - 2]
    if has_horizon and condition == conditions - 2:
        return not reject[base + conditions - 3]
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
def _row_roots(test, row, quartic, quadratic_row, out):
    """Write the roots of column ROW of TEST (L, K) into OUT (4,), NaN-padded."""
    out[:] = np.nan
    if quadratic_row or not quartic:
        # g's quartic is a quadratic: its mean is linear and its variance quadratic in t.
        out[0], out[1] = quadratic_roots(test[0, row], test[1, row], test[2, row])
    else:
        out[0], out[1], out[2], out[3] = polynomial_roots(
            test[0, row], test[1, row], test[2, row], test[3, row], test[4, row])


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
    # Per (test, segment, row): certified >= 0, certified < 0.
    nonnegative = np.empty((tests, SEGMENTS, count), dtype=np.bool_)
    negative = np.empty((tests, SEGMENTS, count), dtype=np.bool_)
    segment_certificates(first, nonnegative[0], negative[0])
    if tests == 2:
        segment_certificates(means, nonnegative[1], negative[1])
    accept = nonnegative[0].copy()
    reject = negative[0].copy()
    for test in range(1, tests):
        accept &= nonnegative[test]
        reject |= negative[test]
    # A segment of a ray is open unless some neighbour rejects all of it: (S, R).
    open_segments = np.ones((SEGMENTS, rays), dtype=np.bool_)
    accept_pair = np.empty((SEGMENTS, links), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            base = link * conditions
            enabled = link_enabled[link]
            accept_pair[segment, link] = _some_accepted(
                accept[segment], base, conditions, has_receding, has_horizon, enabled)
            if _all_rejected(reject[segment], base, conditions, has_receding, has_horizon,
                             enabled):
                open_segments[segment, link_ray[link]] = False
    # Units: (segment, link) on an open segment, not certified accepted there.
    open_unit = np.empty((SEGMENTS, links), dtype=np.bool_)
    for segment in range(SEGMENTS):
        for link in range(links):
            open_unit[segment, link] = (not accept_pair[segment, link]
                                        and open_segments[segment, link_ray[link]])
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
                        reject[segment], base, condition, conditions, has_receding,
                        has_horizon, link_enabled[link]):
                    continue
                for test in range(tests):
                    if not (nonnegative[test, segment, row] or negative[test, segment, row]):
                        undecided[test, segment, row] = True
                        needed[test, row] = True
    roots = np.full((tests, count, _ROOTS), np.nan)
    inside = 0
    for test in range(tests):
        test_rows = first if test == 0 else means
        for row in range(count):
            if not needed[test, row]:
                continue
            # Quiet rows: a variance certified positive needs no cuts at the mean's roots.
            if test == 1 and not bernstein_may_vanish(variances, row):
                continue
            _row_roots(test_rows, row, test_rows.shape[0] == 5,
                       has_receding and row % conditions == 1, roots[test, row])
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
    accepted = np.empty(conditions, dtype=np.bool_)
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
                    accepted[condition] = _horner_column(first, row, midpoint) >= 0.0
                    if tests == 2:
                        accepted[condition] &= _horner_column(means, row, midpoint) >= 0.0
                if not _some_accepted(accepted, 0, conditions, has_receding, has_horizon,
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
