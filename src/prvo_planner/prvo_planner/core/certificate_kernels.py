"""
The certificate compiled (:mod:`.certificate`): wedges, masses, the bounds and their choice.

Three numba functions, compiled for one signature each when this module is first imported
(:mod:`.certificate` imports it on its first bound) and kept in numba's on-disk cache, as the ray
search is (:mod:`.ray_search`; ``./run.sh setup`` compiles every kernel module once after
installing):

* :func:`cut_wedges` cuts each entry's directions of ``w`` into wedges and bounds their masses
  from below (steps 4 and 5 of the proof in :mod:`.certificate`'s docstring);
* :func:`condition_bounds` bounds the planner's whole condition, each stage only where the
  earlier ones fall short (``condition_bound``: a plan's certificates in one call;
  :func:`bounds_until_short` up to the first entry short, for a robot's anchors), or
  ``P(f >= 0)`` or ``P(g >= 0)`` alone (``rvo_certificate``, ``receding_certificate``). Per entry
  and condition (:func:`_certify`): the exact cases (zero covariance, ``S_ww = 0``), else the
  larger of the wedge bound (:func:`_wedge_bounds`, steps 1 to 5) and Cantelli's from the
  moments of :mod:`.moment_kernels`;
* :func:`horizon_bounds` bounds the whole condition by half-planes the segment from ``r`` to
  ``r + tau w`` stays in (:func:`.certificate.horizon_certificate`).

They work entry by entry and wedge by wedge in scalars, with the arithmetic the proof states:
the ranges of the sinusoids of the direction angle over a wedge (:func:`harmonic_range`), the
lengths of ``w`` on a strip, the minima of the folded and half normal over a box of mean and
variance; no (entry, wedge, event) arrays are made. Each entry's bound is its own: it does not
depend on which entries are bounded with it (the planner certifies a robot's anchors one by
one, :func:`bounds_until_short`).

``Phi`` is :func:`ndtr`, cephes' form over the C library's ``erf`` and ``erfc`` (numba cannot
call scipy's ufunc), in the exact cases too: within 2e-14 of ``math.erfc``'s ``Phi``
everywhere, which the bound's ``SLACK`` covers.
"""

import math

from numba import types
import numpy as np

from .certificate import (
    ADAPTIVE_SPAN,
    CONDITION_LIMIT,
    DISC_SIZES,
    HORIZON_DIRECTIONS,
    PSI_SWITCH,
    SLACK,
    STRIP_SIZES,
    WIDENING,
)
from .moment_kernels import condition_moments
from .probability import _CERTAIN_K
from .ray_solver import READ_ONLY_CUBE, READ_ONLY_FLAGS, READ_ONLY_ROWS, READ_ONLY_VECTOR, jit
from .special_kernels import ndtr

_SQRT_HALF = math.sqrt(0.5)
_SQRT_2PI = math.sqrt(2.0 * math.pi)
_TWO_PI = 2.0 * math.pi
# The largest float below pi: an edge that ``mod`` rounds up to pi itself is put there.
_BELOW_PI = float(np.nextafter(math.pi, 0.0))
# The events: J = 3 discs, then 3 strips where a cross-covariance is left. Their miss
# probabilities are exp(-rho^2 / 2) and 2 Phi(-rho) = erfc(rho / sqrt(2)); the disc of size 40
# misses with probability exp(-800), which underflows to 0.
_DISCS = np.array(DISC_SIZES)
_STRIPS = np.array(STRIP_SIZES)
_DISC_MISSES = np.exp(-0.5 * np.square(DISC_SIZES))
_STRIP_MISSES = np.array([math.erfc(size * _SQRT_HALF) for size in STRIP_SIZES])
_EVENTS = len(DISC_SIZES) + len(STRIP_SIZES)

# The methods of :data:`.certificate.METHODS`, by their index there.
_DETERMINISTIC, _KNOWN, _WEDGE, _CANTELLI = range(4)

_ROWS = types.float64[:, ::1]
_VECTOR = types.float64[::1]
_FLAGS = types.boolean[::1]
_CUT_SIGNATURE = types.Tuple((_ROWS, _ROWS, _ROWS, _FLAGS))(
    READ_ONLY_ROWS, READ_ONLY_CUBE, types.int64)
_CONDITION_SIGNATURE = types.Tuple((_VECTOR, types.int64[::1]))(
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_FLAGS,
    types.float64, types.int64, types.boolean)
_SHORT_SIGNATURE = types.Tuple((
    _ROWS, types.int64[::1], _ROWS, types.float64[:, :, ::1], _VECTOR, _VECTOR, _FLAGS))(
    READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_ROWS,
    READ_ONLY_ROWS, READ_ONLY_VECTOR, READ_ONLY_FLAGS)
_HORIZON_SIGNATURE = _VECTOR(READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_VECTOR)
_UNTIL_SIGNATURE = types.Tuple((_VECTOR, types.int64))(
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_VECTOR, READ_ONLY_FLAGS,
    types.float64, types.int64)


@jit(inline='always')
def _ratio(numerator, denominator, zero_by_zero):
    """``numerator / denominator`` for ``denominator >= 0``: ``+-inf`` by 0, ``0 / 0`` given."""
    quotient = numerator / denominator
    return zero_by_zero if quotient != quotient else quotient


@jit()
def harmonic_range(cosine, sine, multiple, start, width):
    """
    Exact range of ``c cos mx + s sin mx`` over the wedge ``[a, a + w]``, ``m`` 1 or 2.

    With ``y = m x`` over ``[m a, m a + m w]`` (``m w <= 2 pi``), the extremes are at the ends or
    at the interior stationary points: the peak ``atan2(s, c)``, of value ``hypot(c, s)``, and the
    trough half a turn from it.

    Returns
    -------
    low, high : float
        The minimum and maximum.

    """
    return _range_over(cosine, sine, _sinusoid(cosine, sine), _wedge_ends(multiple, start, width))


# A bound's sinusoids change per entry and its wedges per wedge: the kernels take the peaks once
# per entry (_sinusoid) and the wedge's ends once per wedge and multiple (_wedge_ends), and so
# call the trigonometric functions 8 times a wedge, not 4 per sinusoid and 2 more per range.
@jit(inline='always')
def _sinusoid(cosine, sine):
    """Return the amplitude ``hypot(c, s)`` and peak ``atan2(s, c)`` of ``c cos y + s sin y``."""
    return math.hypot(cosine, sine), math.atan2(sine, cosine)


@jit(inline='always')
def _wedge_ends(multiple, start, width):
    """Return ``m a``, ``m w`` and the cosines and sines at ``m a`` and ``m (a + w)``."""
    begin = multiple * start
    span = multiple * width
    end = begin + span
    return begin, span, math.cos(begin), math.sin(begin), math.cos(end), math.sin(end)


@jit(inline='always')
def _range_over(cosine, sine, sinusoid, ends):
    """:func:`harmonic_range` from the SINUSOID's (:func:`_sinusoid`) and the wedge's ENDS."""
    amplitude, peak = sinusoid
    begin, span, cos_begin, sin_begin, cos_end, sin_end = ends
    first = cosine * cos_begin + sine * sin_begin
    last = cosine * cos_end + sine * sin_end
    # Python's float % takes the divisor's sign, as numpy.mod does.
    low = -amplitude if (peak + math.pi - begin) % _TWO_PI <= span else min(first, last)
    high = amplitude if (peak - begin) % _TWO_PI <= span else max(first, last)
    return low, high


@jit(inline='always')
def _invertible(xx, xy, yy):
    """Whether ``S_ww = [[xx, xy], [xy, yy]]`` may be inverted: eigenvalue ratio >= the limit."""
    trace = xx + yy
    # From det / tr^2 = ratio / (1 + ratio)^2.
    return xx * yy - xy * xy > CONDITION_LIMIT / (1.0 + CONDITION_LIMIT) ** 2 * trace * trace


@jit()
def _wedge_edges(mu_x, mu_y, xx, xy, yy, pairs, edges):
    """
    Cut the line directions ``[0, pi)`` of ``w`` into PAIRS wedges; write their edges, sorted.

    A quarter of the edges are even over the half turn. The others resolve where the mass is: a
    narrow direction (``|mu_w| > 2 sigma``) gets the directions of ``mu_w + z sigma e``, ``e``
    across ``mu_w``, ``sigma`` the standard deviation of ``w`` along ``e``, for ``z`` even in
    ``[-6, 6)``; a broad one gets more even edges. Every set is nested when ``pairs`` doubles, so
    the cut is refined. EDGES, shape (pairs,), receives each wedge's first edge in ``[0, pi)``.
    """
    even = max(pairs // 4, 1)
    spread = pairs - even
    # sigma |mu_w| without dividing by |mu_w|: (-mu_y, mu_x)' S_ww (-mu_y, mu_x).
    across = math.sqrt(max(mu_y * mu_y * xx - 2.0 * mu_x * mu_y * xy + mu_x * mu_x * yy, 0.0))
    speed_sq = mu_x * mu_x + mu_y * mu_y
    for index in range(even):
        edges[index] = math.pi * index / even
    narrow = speed_sq > 2.0 * across
    heading = math.atan2(mu_y, mu_x)
    for index in range(spread):
        if narrow:
            step = ADAPTIVE_SPAN * (2.0 * index / spread - 1.0)
            edges[even + index] = (heading + math.atan2(across * step, speed_sq)) % math.pi
        else:
            edges[even + index] = math.pi * index / spread
    edges.sort()
    for index in range(pairs):
        edges[index] = min(edges[index], _BELOW_PI)


@jit(inline='always')
def _half_plane(mu_x, mu_y, xx, xy, yy, angle):
    """``Phi`` of the argument for ``P(d(angle) x w > 0)``: ``w`` points into ``(angle, + pi)``."""
    cos, sin = math.cos(angle), math.sin(angle)
    mean = cos * mu_y - sin * mu_x
    variance = xx * sin * sin - 2.0 * xy * sin * cos + yy * cos * cos
    # Zero variance: 1 if the mean is positive, else 0 (the inequality is strict).
    return ndtr(_ratio(mean, math.sqrt(max(variance, 0.0)), -np.inf))


@jit(inline='always')
def _scaled_psi_lower(beta, quadratic):
    """
    Lower bound on ``exp(-C/2) psi(beta)``, ``psi(beta) = int_0^inf y exp(-y^2/2 + beta y) dy``.

    ``psi(beta) = 1 + sqrt(2 pi) beta exp(beta^2 / 2) Phi(beta)``, increasing in ``beta``. Below
    ``beta = -3`` that form cancels; there ``exp(-y^2/2) >= 1 - y^2/2`` gives
    ``psi(beta) >= 1/beta^2 - 3/beta^4``. The bound is >= 0.
    """
    scale = math.exp(-0.5 * quadratic)
    if beta >= PSI_SWITCH:
        value = scale + _SQRT_2PI * beta * ndtr(beta) * math.exp(
            0.5 * (beta * beta - quadratic))
    else:
        inverse_sq = 1.0 / (beta * beta)
        value = scale * inverse_sq * (1.0 - 3.0 * inverse_sq)
    return max(value, 0.0)


@jit(_CUT_SIGNATURE)
def cut_wedges(mean, cov, pairs):
    """
    Each entry's wedges of the directions of ``w``, and lower bounds on their masses.

    They depend on the mean and covariance of ``w`` alone: the bounds on ``f`` and on ``g`` of
    the same entries share them. Let ``m`` and ``m~`` be the masses of a wedge ``W`` and of its
    opposite ``W + pi``.

    * ``m - m~`` is exactly the difference of the half-plane probabilities through the wedge's
      edges, ``P(theta in (a, a + pi)) - P(theta in (b, b + pi))``.
    * ``m >= width * min_W p``, with the density of the direction of ``w ~ N(mu, S)``
      ``p(x) = exp(-C/2) psi(B / sqrt(A)) / (2 pi sqrt(det S) A)``, ``A = d' S^-1 d``,
      ``B = d' S^-1 mu``, ``C = mu' S^-1 mu`` (the density integrated along the ray ``l d``);
      ``psi`` increases, so the minimum is bounded from the exact ranges of the sinusoids ``A``
      and ``B``. Used only where ``S`` may be inverted (else 0).

    So ``m >= max(L, (m - m~) + L~)`` and ``m~ >= max(L~, L - (m - m~))`` with the density bounds
    ``L``, ``L~``.

    Parameters
    ----------
    mean : numpy.ndarray
        Mean of ``z = (r, w)`` per entry, shape (N, 4); only ``w``'s is read.
    cov : numpy.ndarray
        Its covariance, shape (N, 4, 4); only ``S_ww`` is read.
    pairs : int
        K, wedges of the half turn, >= 2.

    Returns
    -------
    start, width : numpy.ndarray
        Each wedge's first edge in ``[0, pi)`` and its width, shape (N, K), the widths summing
        to ``pi`` (wedges of zero width are possible).
    masses : numpy.ndarray
        Lower bounds on the masses of the wedges and then of their opposites, shape (N, 2 K).
    invertible : numpy.ndarray
        Whether ``S_ww`` may be inverted, shape (N,).

    """
    count = mean.shape[0]
    start = np.empty((count, pairs))
    width = np.empty((count, pairs))
    masses = np.empty((count, 2 * pairs))
    invertible = np.empty(count, dtype=np.bool_)
    half_planes = np.empty(pairs + 1)
    for entry in range(count):
        mu_x, mu_y = mean[entry, 2], mean[entry, 3]
        xx, xy, yy = cov[entry, 2, 2], cov[entry, 2, 3], cov[entry, 3, 3]
        edges = start[entry]
        _wedge_edges(mu_x, mu_y, xx, xy, yy, pairs, edges)
        for wedge in range(pairs - 1):
            width[entry, wedge] = edges[wedge + 1] - edges[wedge]
        width[entry, pairs - 1] = edges[0] + math.pi - edges[pairs - 1]
        for wedge in range(pairs):
            half_planes[wedge] = _half_plane(mu_x, mu_y, xx, xy, yy, edges[wedge])
        half_planes[pairs] = _half_plane(mu_x, mu_y, xx, xy, yy,
                                         edges[pairs - 1] + width[entry, pairs - 1])
        usable = _invertible(xx, xy, yy)
        invertible[entry] = usable
        if not usable:
            # No density bound: the masses are the half planes' differences alone.
            for wedge in range(pairs):
                difference = half_planes[wedge] - half_planes[wedge + 1]
                masses[entry, wedge] = max(0.0, difference)
                masses[entry, pairs + wedge] = max(0.0, -difference)
            continue
        determinant = xx * yy - xy * xy
        # S^-1 from the adjugate; B = d' S^-1 mu is a sinusoid of x, A = d' S^-1 d a constant
        # plus one of 2x.
        pxx, pxy, pyy = yy / determinant, -xy / determinant, xx / determinant
        pulled_x, pulled_y = pxx * mu_x + pxy * mu_y, pxy * mu_x + pyy * mu_y
        quadratic = pulled_x * mu_x + pulled_y * mu_y
        constant = 0.5 * (pxx + pyy)
        # A >= 1 / lambda_max(S) > 0; the floor keeps rounding from reaching 0.
        floor = 0.5 / (xx + yy)
        scale = (1.0 - WIDENING) / (2.0 * math.pi * math.sqrt(determinant))
        a_c = 0.5 * (pxx - pyy)
        b_peak = _sinusoid(pulled_x, pulled_y)
        a_peak = _sinusoid(a_c, pxy)
        for wedge in range(pairs):
            once = _wedge_ends(1.0, edges[wedge], width[entry, wedge])
            twice = _wedge_ends(2.0, edges[wedge], width[entry, wedge])
            b_low, b_high = _range_over(pulled_x, pulled_y, b_peak, once)
            a_low, a_high = _range_over(a_c, pxy, a_peak, twice)
            a_low, a_high = math.sqrt(max(constant + a_low, floor)), constant + a_high
            densities = scale * width[entry, wedge] / a_high
            # The smallest B / sqrt(A) over the wedge (and its opposite, where B changes sign):
            # a positive B over the largest A, a negative one over the smallest.
            own = b_low / math.sqrt(a_high) if b_low >= 0.0 else b_low / a_low
            opposite = -b_high / math.sqrt(a_high) if -b_high >= 0.0 else -b_high / a_low
            own = densities * _scaled_psi_lower(own, quadratic)
            opposite = densities * _scaled_psi_lower(opposite, quadratic)
            difference = half_planes[wedge] - half_planes[wedge + 1]
            masses[entry, wedge] = max(own, difference + opposite)
            masses[entry, pairs + wedge] = max(opposite, own - difference)
    return start, width, masses, invertible


@jit(inline='always')
def _folded_normal_minimum(low, high, sd_low, sd_high, radius):
    """
    Lower bound on ``F = P(|X| >= R)``, ``X ~ N(m, s^2)``, over a box of ``m`` and ``s``.

    ``1 - F`` is the probability of the band ``|X| < R``,
    ``Phi((R - |m|) / s) - Phi((-R - |m|) / s)``, which decreases in ``|m|``: it is largest at the
    smallest ``|m|`` of the box, ``a`` (0 if ``m`` may change sign), moved towards 0 by a
    relative ``WIDENING``. There its first term is largest at the smallest ``s`` when
    ``a <= R`` (else at the largest) and its second smallest at the smallest ``s``. An empty box
    (``low > high``) gives 1.
    """
    if low > high:
        return 1.0
    closest = 0.0 if low <= 0.0 <= high else min(abs(low), abs(high))
    size = max(abs(low), abs(high))
    closest = max(closest - WIDENING * (size if math.isfinite(size) else 0.0), 0.0)
    near_side = radius - closest
    band = (ndtr(_ratio(near_side, sd_low if near_side >= 0.0 else sd_high, 0.0))
            - ndtr(_ratio(-radius - closest, sd_low, -np.inf)))
    return min(max(1.0 - band, 0.0), 1.0)


@jit(inline='always')
def _half_normal_minimum(low, high, sd_low, sd_high):
    """
    Lower bound on ``G = P(X >= 0)``, ``X ~ N(m, s^2)``, over a box of ``m`` and ``s``.

    ``Phi(m / s)`` at the smallest ``m`` (moved down by a relative ``WIDENING``), and at the
    largest ``s`` if that ``m >= 0`` (else at the smallest). An empty box gives 1.
    """
    if low > high:
        return 1.0
    size = max(abs(low), abs(high))
    smallest = low - WIDENING * (size if math.isfinite(size) else 0.0)
    return ndtr(_ratio(smallest, sd_high if smallest >= 0.0 else sd_low, np.inf))


@jit(inline='always')
def _strip_lengths(c_low, c_high, t_low, t_high):
    """
    Range of the length ``l`` of ``w = l d`` on a wedge where ``c = e . d`` is in a range.

    On the strip ``e . w`` in ``[t_low, t_high]``, ``l = (e . w) / c``: bounded where ``c`` keeps
    its sign over the wedge, ``[0, inf)`` where it may vanish. Returns ``low > high`` where the
    strip misses the wedge.
    """
    if c_low > 0.0:
        if t_high < 0.0:
            return np.inf, -np.inf
        return max(t_low, 0.0) / c_high, t_high / c_low
    if c_high < 0.0:
        if t_low > 0.0:
            return np.inf, -np.inf
        return max(-t_high, 0.0) / -c_low, -t_low / -c_high
    return 0.0, np.inf


@jit(inline='always')
def _product(a, b):
    """Return ``a b``, with ``0 inf`` taken as 0 (an unbounded length times a zero gain)."""
    value = a * b
    return 0.0 if value != value else value


@jit(inline='always')
def _interval_product(low, high, factor_low, factor_high):
    """Range of ``x y`` for ``x`` in ``[low, high]``, ``y`` in a range."""
    corners = (_product(low, factor_low), _product(low, factor_high),
               _product(high, factor_low), _product(high, factor_high))
    return (min(min(corners[0], corners[1]), min(corners[2], corners[3])),
            max(max(corners[0], corners[1]), max(corners[2], corners[3])))


@jit()
def _split(mean, cov, across, invertible, rows, split):
    """
    Write ``r^ = r + T w`` split into ``r'``, independent of ``w``, and ``K (w - mu_w)``.

    ``T = -lambda I`` for ``f`` (ACROSS) and ``kappa J`` for ``g``, the shift that leaves the
    least cross-covariance ``D = S_rw + T S_ww`` (:mod:`.certificate`, step 1); ``K = D S_ww^-1``
    the gain (0 where ``D = 0`` or ``S_ww`` is not inverted). SPLIT (R, 12) receives per entry
    of ROWS (R,) the mean of ``r'`` (2), ``S' = Cov(r^) - D S_ww^-1 D'`` (``xx, xy, yy``), ``K``
    (row-major, 4), the reach ``||D S_ww^-1/2||_2``, the scale of the entries of ``S'`` (for
    widening its ranges) and whether the split is known (``S_ww`` inverted or ``D = 0``: 1,
    else 0).
    """
    for row in range(rows.shape[0]):
        entry = rows[row]
        c = cov[entry]
        xx, xy, yy = c[2, 2], c[2, 3], c[3, 3]
        trace = xx + yy
        if xx == 0.0 and xy == 0.0 and c[3, 2] == 0.0 and yy == 0.0:
            trace = 1.0
        # T = [[t00, t01], [t10, t11]].
        if across:
            t00 = t11 = -((c[0, 2] + c[1, 3]) / trace)
            t01 = t10 = 0.0
        else:
            kappa = (c[0, 3] - c[1, 2]) / trace
            t00 = t11 = 0.0
            t01, t10 = -kappa, kappa
        # T S_ww and T S_ww T'.
        tw00, tw01 = t00 * c[2, 2] + t01 * c[3, 2], t00 * c[2, 3] + t01 * c[3, 3]
        tw10, tw11 = t10 * c[2, 2] + t11 * c[3, 2], t10 * c[2, 3] + t11 * c[3, 3]
        tt00, tt01 = tw00 * t00 + tw01 * t01, tw00 * t10 + tw01 * t11
        tt10, tt11 = tw10 * t00 + tw11 * t01, tw10 * t10 + tw11 * t11
        # S_rw T'.
        rt00, rt01 = c[0, 2] * t00 + c[0, 3] * t01, c[0, 2] * t10 + c[0, 3] * t11
        rt10, rt11 = c[1, 2] * t00 + c[1, 3] * t01, c[1, 2] * t10 + c[1, 3] * t11
        # D = S_rw + T S_ww and Cov(r^) = S_rr + S_rw T' + T S_wr + T S_ww T'.
        d00, d01, d10, d11 = c[0, 2] + tw00, c[0, 3] + tw01, c[1, 2] + tw10, c[1, 3] + tw11
        hat00 = c[0, 0] + rt00 + rt00 + tt00
        hat01 = c[0, 1] + rt01 + rt10 + tt01
        hat11 = c[1, 1] + rt11 + rt11 + tt11
        no_cross = d00 == 0.0 and d01 == 0.0 and d10 == 0.0 and d11 == 0.0
        k00 = k01 = k10 = k11 = 0.0
        if invertible[entry] and not no_cross:
            determinant = xx * yy - xy * xy
            i00, i01, i11 = yy / determinant, -xy / determinant, xx / determinant
            k00, k01 = d00 * i00 + d01 * i01, d00 * i01 + d01 * i11
            k10, k11 = d10 * i00 + d11 * i01, d10 * i01 + d11 * i11
        # K D', symmetrised.
        e00 = k00 * d00 + k01 * d01
        e11 = k10 * d10 + k11 * d11
        e01 = 0.5 * ((k00 * d10 + k01 * d11) + (k10 * d00 + k11 * d01))
        # The largest eigenvalue of D S^-1 D', grown by the relative error of the inverse.
        reach = math.sqrt(max(0.5 * (e00 + e11) + math.hypot(0.5 * (e00 - e11), e01), 0.0))
        split[row, 0] = mean[entry, 0] + t00 * mean[entry, 2] + t01 * mean[entry, 3]
        split[row, 1] = mean[entry, 1] + t10 * mean[entry, 2] + t11 * mean[entry, 3]
        split[row, 2] = hat00 - e00
        split[row, 3] = hat01 - e01
        split[row, 4] = hat11 - e11
        split[row, 5], split[row, 6], split[row, 7], split[row, 8] = k00, k01, k10, k11
        split[row, 9] = reach * (1.0 + 1e-6)
        split[row, 10] = (abs(c[0, 0]) + abs(c[0, 1]) + abs(c[1, 0]) + abs(c[1, 1])
                            + 2.0 * (abs(rt00) + abs(rt01) + abs(rt10) + abs(rt11))
                            + abs(tt00) + abs(tt01) + abs(tt10) + abs(tt11)
                            + abs(e00) + 2.0 * abs(e01) + abs(e11))
        split[row, 11] = invertible[entry] or no_cross


@jit()
def _wedge_bounds(mean, cov, radius, across, rows, start, width, masses, invertible,
                  probability, usable):
    """
    Write the wedge bound of ``f`` (ACROSS) or of ``g`` of the entries ROWS, and where it holds.

    After the split (:func:`_split`), ``r^ . v`` given ``w`` is normal with variance
    ``s^2 = v' S' v`` and mean ``m``; ``v`` is the normal ``n`` for ``f`` and the direction ``d``
    for ``g``. On a wedge, ``s^2`` ranges over the range of its sinusoid (widened by a relative
    ``WIDENING`` of its scale); on the disc of size ``rho``, ``m`` is within
    ``rho ||D S_ww^-1/2||`` of ``mu^ . v``; on the strip, ``m = a + l b`` with the ranges of
    ``a = (mu^ - K mu_w) . v``, of ``b = v' K d`` and of ``l`` (:func:`_strip_lengths`). On the
    opposite wedge ``v`` and ``d`` change sign: ``mu^ . v`` and ``a`` do, ``b`` and ``s^2`` do
    not. Over each box the conditional probability is at least the folded (``f``) or half
    (``g``) normal's minimum. The true masses are at least the wedges' and sum to one, so the
    conditional probability averages to at least ``sum q_k F_k + (1 - sum q_k) min F``; masses
    that sum above one by rounding are scaled down (they stay lower bounds). Each event's miss
    probability is then subtracted, the best event kept, and ``SLACK`` subtracted. The strips
    are tried for an entry with a cross-covariance left after the shift: an entry's bound is
    its own, whatever else is bounded with it.

    Parameters
    ----------
    mean : numpy.ndarray
        Mean of ``z = (r, w)``, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z``, shape (N, 4, 4).
    radius : numpy.ndarray
        ``R`` per entry, shape (N,) (unused for ``g``).
    across : bool
        The bound of ``f`` (else of ``g``).
    rows : numpy.ndarray
        The entries to bound, shape (R,).
    start, width, masses, invertible : numpy.ndarray
        The entries' wedges, shapes (N, K), (N, K), (N, 2 K), (N,) (:func:`cut_wedges`).
    probability : numpy.ndarray
        Receives the bound per entry of ROWS, shape (R,) (not clipped to [0, 1]).
    usable : numpy.ndarray
        Receives False where ``S_ww`` is not inverted but a cross-covariance is left: the
        split, and so the bound, is unknown there, shape (R,).

    """
    count, pairs = rows.shape[0], start.shape[1]
    split = np.empty((count, 12))
    _split(mean, cov, across, invertible, rows, split)
    claimed = np.empty(_EVENTS)
    least = np.empty(_EVENTS)
    lows = np.empty(_EVENTS)
    highs = np.empty(_EVENTS)
    sign = -1.0 if across else 1.0
    for row in range(count):
        entry = rows[row]
        # The strips where a cross-covariance is left. Without, m = a on every disc and the
        # largest disc misses nothing: a strip could gain only where it leaves out the wedges
        # that bound the unclaimed mass, never seen in 46,887 entries (docs/results.md, 5.24).
        strips = split[row, 9] > 0.0
        events = _EVENTS if strips else len(DISC_SIZES)
        usable[row] = split[row, 11] != 0.0
        mu_x, mu_y = mean[entry, 2], mean[entry, 3]
        hat_x, hat_y = split[row, 0], split[row, 1]
        k00, k01, k10, k11 = split[row, 5], split[row, 6], split[row, 7], split[row, 8]
        reach = split[row, 9]
        widening = WIDENING * split[row, 10]
        # The sinusoids of x: mu^ . v (m = 1) and s^2 = v' S' v (m = 2); for v = n(x) the
        # linear coefficients are (-y, x) and the double-angle part changes sign.
        mean_c, mean_s = (-hat_y, hat_x) if across else (hat_x, hat_y)
        var_constant = 0.5 * (split[row, 2] + split[row, 4])
        var_c, var_s = sign * 0.5 * (split[row, 2] - split[row, 4]), sign * split[row, 3]
        # The strips' terms, set where they are tried.
        speed = e_x = e_y = spread = a_c = a_s = b_constant = b_c = b_s = 0.0
        c_low = c_high = a_low = a_high = b_low = b_high = 0.0
        if strips:
            speed = math.hypot(mu_x, mu_y)
            e_x, e_y = (mu_x / speed, mu_y / speed) if speed > 0.0 else (1.0, 0.0)
            spread = math.sqrt(max(e_x * e_x * cov[entry, 2, 2] + 2.0 * e_x * e_y
                                   * cov[entry, 2, 3] + e_y * e_y * cov[entry, 3, 3], 0.0))
            # a = (mu^ - K mu_w) . v, and b = v' K d = constant + a sinusoid of 2x.
            a_x = hat_x - (k00 * mu_x + k01 * mu_y)
            a_y = hat_y - (k10 * mu_x + k11 * mu_y)
            a_c, a_s = (-a_y, a_x) if across else (a_x, a_y)
            if across:
                b_constant = 0.5 * (k01 - k10)
                b_c, b_s = -0.5 * (k01 + k10), 0.5 * (k00 - k11)
            else:
                b_constant = 0.5 * (k00 + k11)
                b_c, b_s = 0.5 * (k00 - k11), 0.5 * (k01 + k10)
        mean_peak, var_peak = _sinusoid(mean_c, mean_s), _sinusoid(var_c, var_s)
        c_peak = a_peak = b_peak = (0.0, 0.0)
        if strips:
            c_peak, a_peak, b_peak = _sinusoid(e_x, e_y), _sinusoid(a_c, a_s), _sinusoid(b_c, b_s)
        total = 0.0
        for side in range(2 * pairs):
            total += masses[entry, side]
        normaliser = max(total, 1.0)
        claimed[:events] = 0.0
        least[:events] = np.inf
        mass_sum = 0.0
        for wedge in range(pairs):
            begin, span = start[entry, wedge], width[entry, wedge]
            once = _wedge_ends(1.0, begin, span)
            twice = _wedge_ends(2.0, begin, span)
            mean_low, mean_high = _range_over(mean_c, mean_s, mean_peak, once)
            var_low, var_high = _range_over(var_c, var_s, var_peak, twice)
            sd_low = math.sqrt(max(var_constant + var_low - widening, 0.0))
            sd_high = math.sqrt(max(var_constant + var_high + widening, 0.0))
            if strips:
                c_low, c_high = _range_over(e_x, e_y, c_peak, once)
                a_low, a_high = _range_over(a_c, a_s, a_peak, once)
                b_low, b_high = _range_over(b_c, b_s, b_peak, twice)
                b_low, b_high = b_constant + b_low, b_constant + b_high
            for side in range(2):
                # The opposite wedge: the linear ranges negated.
                if side == 1:
                    mean_low, mean_high = -mean_high, -mean_low
                    if strips:
                        c_low, c_high = -c_high, -c_low
                        a_low, a_high = -a_high, -a_low
                for disc in range(len(DISC_SIZES)):
                    lows[disc] = mean_low - reach * _DISCS[disc]
                    highs[disc] = mean_high + reach * _DISCS[disc]
                if strips:
                    for strip in range(len(STRIP_SIZES)):
                        extent = spread * _STRIPS[strip]
                        l_low, l_high = _strip_lengths(c_low, c_high, speed - extent,
                                                       speed + extent)
                        event = len(DISC_SIZES) + strip
                        if l_low > l_high:
                            lows[event], highs[event] = np.inf, -np.inf
                        else:
                            product_low, product_high = _interval_product(l_low, l_high,
                                                                          b_low, b_high)
                            lows[event] = a_low + product_low
                            highs[event] = a_high + product_high
                mass = masses[entry, side * pairs + wedge] / normaliser
                mass_sum += mass
                for event in range(events):
                    if across:
                        minimum = _folded_normal_minimum(lows[event], highs[event], sd_low,
                                                         sd_high, radius[entry])
                    else:
                        minimum = _half_normal_minimum(lows[event], highs[event], sd_low,
                                                       sd_high)
                    claimed[event] += mass * minimum
                    least[event] = min(least[event], minimum)
        best = -np.inf
        for event in range(events):
            miss = (_DISC_MISSES[event] if event < len(DISC_SIZES)
                    else _STRIP_MISSES[event - len(DISC_SIZES)])
            best = max(best, claimed[event] + (1.0 - mass_sum) * least[event] - miss)
        probability[row] = best - SLACK


@jit(inline='always')
def _half_plane_bound(angle, r_x, r_y, rxx, rxy, ryy, p_x, p_y, pxx, pxy, pyy, radius):
    """
    ``1 - Phi((R - e . mu_r) / s_r) - Phi((R - e . mu_p) / s_p)`` for ``e`` at ANGLE.

    The probability that both ends of the segment lie in the half-plane ``e . x >= R``, at
    least; an end exactly on the line with no spread still lies in the closed half-plane.
    """
    cos, sin = math.cos(angle), math.sin(angle)
    bound = 1.0
    for x, y, xx, xy, yy in ((r_x, r_y, rxx, rxy, ryy), (p_x, p_y, pxx, pxy, pyy)):
        along = cos * x + sin * y - radius
        spread = math.sqrt(max(cos * cos * xx + 2.0 * cos * sin * xy + sin * sin * yy, 0.0))
        bound -= ndtr(-_ratio(along, spread, np.inf))
    return bound


@jit()
def _horizon_bound(mean, cov, entry, big_r, tau):
    """
    Return the horizon bound of ENTRY at ``R = big_r``, ``tau``, clipped to [0, 1].

    The segment from ``r`` to ``p = r + tau w`` misses the disc of radius ``R`` when both ends
    lie in a half-plane ``e . x >= R``; for each ``e`` that has probability at least one less
    the two normal tails of ``e . r`` and ``e . p``. The largest over ``HORIZON_DIRECTIONS``
    even directions and those of ``mu_r``, ``mu_p`` and their bisector is kept, less
    ``SLACK``.
    """
    c = cov[entry]
    r_x, r_y = mean[entry, 0], mean[entry, 1]
    p_x, p_y = r_x + tau * mean[entry, 2], r_y + tau * mean[entry, 3]
    # Cov(p) = S_rr + tau (S_rw + S_wr) + tau^2 S_ww.
    pxx = c[0, 0] + tau * (c[0, 2] + c[0, 2]) + tau * tau * c[2, 2]
    pxy = c[0, 1] + tau * (c[0, 3] + c[1, 2]) + tau * tau * c[2, 3]
    pyy = c[1, 1] + tau * (c[1, 3] + c[1, 3]) + tau * tau * c[3, 3]
    best = -np.inf
    for direction in range(HORIZON_DIRECTIONS):
        best = max(best, _half_plane_bound(
            _TWO_PI * direction / HORIZON_DIRECTIONS, r_x, r_y, c[0, 0], c[0, 1], c[1, 1],
            p_x, p_y, pxx, pxy, pyy, big_r))
    toward_r, toward_p = math.atan2(r_y, r_x), math.atan2(p_y, p_x)
    bisector = 0.5 * (toward_r + toward_p)
    if abs(toward_r - toward_p) > math.pi:
        bisector += math.pi
    for angle in (toward_r, toward_p, bisector):
        best = max(best, _half_plane_bound(angle, r_x, r_y, c[0, 0], c[0, 1], c[1, 1],
                                           p_x, p_y, pxx, pxy, pyy, big_r))
    return min(max(best - SLACK, 0.0), 1.0)


@jit()
def _check(mean, cov, radius):
    """Raise ValueError unless MEAN (N, 4), COV (N, 4, 4) and RADIUS (N,) fit and are finite."""
    count = mean.shape[0]
    if (mean.shape[1] != 4 or cov.shape[0] != count or cov.shape[1] != 4 or cov.shape[2] != 4
            or radius.shape[0] != count):
        raise ValueError('mean must have shape (N, 4), cov (N, 4, 4) and radius (N,)')
    for entry in range(count):
        for row in range(4):
            if not math.isfinite(mean[entry, row]):
                raise ValueError('mean and cov must be finite')
            for column in range(4):
                if not math.isfinite(cov[entry, row, column]):
                    raise ValueError('mean and cov must be finite')


@jit(_HORIZON_SIGNATURE)
def horizon_bounds(mean, cov, radius, horizon):
    """
    Return the horizon bound per entry (``certificate.horizon_certificate``).

    Parameters
    ----------
    mean : numpy.ndarray
        Mean of ``z = (r, w)``, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z``, shape (N, 4, 4).
    radius, horizon : numpy.ndarray
        ``R`` and ``tau`` per entry, shape (N,).

    Returns
    -------
    numpy.ndarray
        The bound per entry (:func:`_horizon_bound`), shape (N,).

    """
    _check(mean, cov, radius)
    if horizon.shape[0] != mean.shape[0]:
        raise ValueError('horizon must have one value per entry')
    bounds = np.empty(mean.shape[0])
    for entry in range(mean.shape[0]):
        tau = horizon[entry]
        if not (math.isfinite(tau) and tau > 0.0):
            raise ValueError('horizon must be finite and > 0')
        bounds[entry] = _horizon_bound(mean, cov, entry, radius[entry], tau)
    return bounds


@jit()
def _floors(mean, cov, radius):
    """
    ``E`` and ``Var`` of ``f`` and of ``g`` per entry, shape (N, 1, 2) each.

    The moments of :func:`.moment_kernels.condition_moments` at a zero command (lead 0: the mean
    of ``z`` is MEAN itself), with the gate; ``g``'s do not depend on the radius.
    """
    count = mean.shape[0]
    zeros = np.zeros(count)
    return condition_moments(mean, cov, radius, np.zeros((1, 1, 2)), zeros, zeros, True, False)


@jit(inline='always')
def _cantelli(expectation, variance):
    """Cantelli's ``k^2 / (1 + k^2)`` of ``k = E / sd`` (0 when ``E < 0``; 1 when exact)."""
    if not expectation >= 0.0:
        return -SLACK
    expectation_sq = expectation * expectation
    bound = expectation_sq / (expectation_sq + max(variance, 0.0))
    return (1.0 if bound != bound else bound) - SLACK


@jit(inline='always')
def _known(mean, cov, entry, big_r, across):
    """
    ``P(f >= 0)`` (ACROSS) or ``P(g >= 0)`` less ``SLACK`` where ``S_ww = 0``.

    ``w = mu_w`` exactly. ``f >= 0`` iff ``|r . n| >= R`` for ``mu_w``'s unit normal ``n``, a
    folded normal; ``g = r . mu_w`` is normal. ``w = 0`` gives ``f = g = 0``: probability 1.
    """
    r_x, r_y, w_x, w_y = mean[entry, 0], mean[entry, 1], mean[entry, 2], mean[entry, 3]
    c = cov[entry]
    if across:
        speed = math.hypot(w_x, w_y)
        if not speed > 0.0:
            return 1.0
        n_x, n_y = w_y / speed, -w_x / speed
        offset = r_x * n_x + r_y * n_y
        spread = math.sqrt(max(n_x * (c[0, 0] * n_x + c[0, 1] * n_y)
                               + n_y * (c[1, 0] * n_x + c[1, 1] * n_y), 0.0))
        return (ndtr(_ratio(offset - big_r, spread, np.inf))
                + ndtr(_ratio(-offset - big_r, spread, np.inf))) - SLACK
    if w_x == 0.0 and w_y == 0.0:
        return 1.0
    spread = math.sqrt(max(w_x * (c[0, 0] * w_x + c[0, 1] * w_y)
                           + w_y * (c[1, 0] * w_x + c[1, 1] * w_y), 0.0))
    return ndtr(_ratio(r_x * w_x + r_y * w_y, spread, np.inf)) - SLACK


@jit()
def _certify(mean, cov, radius, across, rows, start, width, masses, invertible, moments,
             probability, method):
    """
    Write the bound of ``f`` (ACROSS) or of ``g`` of each entry of ROWS (R,), and its method.

    Per entry the exact cases first: zero covariance (1 or 0 as the condition holds at the
    mean), ``S_ww = 0`` (:func:`_known`); else the wedge bound (the entries of ROWS one batch,
    :func:`_wedge_bounds`) where it applies and beats Cantelli's of MOMENTS (:func:`_floors`),
    else Cantelli's. PROBABILITY (R,) receives the bound clipped to [0, 1], METHOD (R,) its
    index in :data:`.certificate.METHODS`.
    """
    count = rows.shape[0]
    wedge = np.empty(count)
    usable = np.empty(count, dtype=np.bool_)
    _wedge_bounds(mean, cov, radius, across, rows, start, width, masses, invertible, wedge,
                  usable)
    column = 0 if across else 1
    for row in range(count):
        entry = rows[row]
        c = cov[entry]
        deterministic = True
        known = True
        for index in range(4):
            for other in range(4):
                if c[index, other] != 0.0:
                    deterministic = False
                    if index >= 2 and other >= 2:
                        known = False
        r_x, r_y, w_x, w_y = mean[entry, 0], mean[entry, 1], mean[entry, 2], mean[entry, 3]
        if deterministic:
            if across:
                cross = r_x * w_y - r_y * w_x
                holds = cross * cross - radius[entry] * radius[entry] * (
                    w_x * w_x + w_y * w_y) >= 0.0
            else:
                holds = r_x * w_x + r_y * w_y >= 0.0
            value, kind = (1.0 if holds else 0.0), _DETERMINISTIC
        elif known:
            value, kind = _known(mean, cov, entry, radius[entry], across), _KNOWN
        else:
            value = _cantelli(moments[0][entry, 0, column], moments[1][entry, 0, column])
            kind = _CANTELLI
            if usable[row] and wedge[row] > value:
                value, kind = wedge[row], _WEDGE
        probability[row] = 0.0 if value < 0.0 else (1.0 if value > 1.0 else value)
        method[row] = kind


@jit(_CONDITION_SIGNATURE)
def condition_bounds(mean, cov, radius, required, gated, horizon, pairs, rvo):
    """
    Return the bound of the accepted condition per entry, computed as far as needed.

    ``condition_bound`` of :mod:`.certificate`: the bound of ``f`` on every entry (RVO); where
    it falls short of REQUIRED and the gate counts (GATED), the larger with the bound of ``g``,
    computed on exactly those entries as one batch; where that too falls short and HORIZON is
    finite, the larger with the horizon bound (:func:`_horizon_bound`). The wedges and the
    moments of ``f`` and ``g`` are computed once for every entry. Without RVO the bound of
    ``g`` alone on the GATED entries (``receding_certificate``, every entry gated); with RVO
    and no entry gated the bound of ``f`` alone (``rvo_certificate``). One kernel serves the
    three, so that the wedge bound is compiled once.

    Parameters
    ----------
    mean : numpy.ndarray
        Mean of ``z = (r, w)``, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z``, shape (N, 4, 4).
    radius, required : numpy.ndarray
        ``R`` and the probability to certify per entry, shape (N,).
    gated : numpy.ndarray
        Whether the gate counts per entry, shape (N,).
    horizon : float
        ``tau`` [s]; ``inf``: no horizon pair.
    pairs : int
        K, wedges of the half turn, >= 2.
    rvo : bool
        Whether the bound of ``f`` comes first (else only ``g``'s is computed).

    Returns
    -------
    bounds : numpy.ndarray
        The bound per entry, in [0, 1], shape (N,); 0 for an entry with neither bound.
    method : numpy.ndarray
        Per entry the index in :data:`.certificate.METHODS` of the last bound of ``f`` or ``g``
        computed for it (-1 for none), shape (N,).

    """
    _check(mean, cov, radius)
    count = mean.shape[0]
    if required.shape[0] != count or gated.shape[0] != count:
        raise ValueError('required and gated must have one value per entry')
    start, width, masses, invertible = cut_wedges(mean, cov, pairs)
    moments = _floors(mean, cov, radius)
    bounds = np.zeros(count)
    method = np.full(count, -1, dtype=np.int64)
    finite = math.isfinite(horizon)
    rows = np.empty(count, dtype=np.int64)
    # The stages: f, then g. ACROSS is not a constant, so that _certify is compiled once.
    for stage in range(2):
        across = stage == 0
        # Every entry for f; for g the gated entries f leaves short.
        size = 0
        for entry in range(count):
            if rvo if across else gated[entry] and (not rvo or bounds[entry] < required[entry]):
                rows[size] = entry
                size += 1
        if size == 0:
            continue
        values = np.empty(size)
        kinds = np.empty(size, dtype=np.int64)
        _certify(mean, cov, radius, across, rows[:size], start, width, masses, invertible,
                 moments, values, kinds)
        for row in range(size):
            entry = rows[row]
            bounds[entry] = max(bounds[entry], values[row])
            method[entry] = kinds[row]
            if not across and finite and bounds[entry] < required[entry]:
                bounds[entry] = max(bounds[entry], _horizon_bound(mean, cov, entry,
                                                                  radius[entry], horizon))
    return bounds, method


@jit(_UNTIL_SIGNATURE)
def bounds_until_short(mean, cov, radius, required, gated, horizon, pairs):
    """
    :func:`condition_bounds` of the entries in order, up to the first that falls short.

    Whether a velocity is certified against every neighbour is settled by its first neighbour
    short of REQUIRED; each entry's bound is its own, so the bounds computed are those of one
    call over all entries. The arguments as :func:`condition_bounds`'s (RVO on).

    Returns
    -------
    bounds : numpy.ndarray
        The bound per entry, shape (N,); only the first DONE are computed (0 after).
    done : int
        How many entries were bounded: all N, or up to and with the first short one.
    """
    count = mean.shape[0]
    bounds = np.zeros(count)
    for entry in range(count):
        end = entry + 1
        bounds[entry] = condition_bounds(mean[entry:end], cov[entry:end], radius[entry:end],
                                         required[entry:end], gated[entry:end], horizon, pairs,
                                         True)[0][0]
        if bounds[entry] < required[entry]:
            return bounds, end
    return bounds, count


@jit(_SHORT_SIGNATURE)
def short_entries(origin, lead, cov, radius, velocities, achieved, required, gated):
    """
    Cantelli's bound per velocity and neighbour, and the entries where it falls short.

    Cantelli's bound ``k^2 / (1 + k^2)`` of the achieved margin ``max(k, 0)`` (1 from
    ``k = 1e8`` on, as :func:`.probability.eta_from_k`) is the floor of the planner's
    certified bounds; where it falls short of the REQUIRED probability, the entry's arguments
    of :func:`.certificate.condition_bound` are gathered, velocity-major.

    Parameters
    ----------
    origin : numpy.ndarray
        Mean of ``z`` at ``v_c = 0`` per neighbour, shape (n, 4).
    lead : numpy.ndarray
        ``1 / rho`` per neighbour, shape (n,): the mean of ``z`` at ``v_c`` is ORIGIN plus
        ``lead v_c`` in its velocity components.
    cov, radius
        Covariance of ``z`` (n, 4, 4) and ``R`` (n,) per neighbour.
    velocities : numpy.ndarray
        The commanded velocities to certify, shape (V, 2).
    achieved : numpy.ndarray
        The margin ``k`` each meets per neighbour, shape (V, n).
    required : numpy.ndarray
        The probability to certify per neighbour, shape (n,).
    gated : numpy.ndarray
        Whether the gate counts per neighbour, shape (n,).

    Returns
    -------
    floors : numpy.ndarray
        Cantelli's bound per entry, shape (V, n).
    short : numpy.ndarray
        The short entries' flat indices into FLOORS, shape (S,).
    mean, cov, radius, required, gated : numpy.ndarray
        Per short entry the mean of ``z`` at its velocity (S, 4), and its neighbour's
        covariance (S, 4, 4), ``R``, required probability and gate (S,).

    """
    count, neighbours = achieved.shape
    floors = np.empty((count, neighbours))
    entries = 0
    for velocity in range(count):
        for neighbour in range(neighbours):
            margin = max(achieved[velocity, neighbour], 0.0)
            if margin >= _CERTAIN_K:
                floor = 1.0
            else:
                square = margin * margin
                floor = square / (1.0 + square)
            floors[velocity, neighbour] = floor
            if floor < required[neighbour]:
                entries += 1
    short = np.empty(entries, dtype=np.int64)
    mean = np.empty((entries, 4))
    short_cov = np.empty((entries, 4, 4))
    short_radius = np.empty(entries)
    short_required = np.empty(entries)
    short_gated = np.empty(entries, dtype=np.bool_)
    entry = 0
    for velocity in range(count):
        for neighbour in range(neighbours):
            if floors[velocity, neighbour] < required[neighbour]:
                short[entry] = velocity * neighbours + neighbour
                mean[entry, 0] = origin[neighbour, 0]
                mean[entry, 1] = origin[neighbour, 1]
                mean[entry, 2] = origin[neighbour, 2] + lead[neighbour] * velocities[velocity, 0]
                mean[entry, 3] = origin[neighbour, 3] + lead[neighbour] * velocities[velocity, 1]
                for row in range(4):
                    for column in range(4):
                        short_cov[entry, row, column] = cov[neighbour, row, column]
                short_radius[entry] = radius[neighbour]
                short_required[entry] = required[neighbour]
                short_gated[entry] = gated[neighbour]
                entry += 1
    return floors, short, mean, short_cov, short_radius, short_required, short_gated
