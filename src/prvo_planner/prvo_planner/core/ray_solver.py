"""
Feasible speed sets along candidate rays: the compiled root finders and certificates.

Along a ray the commanded velocity is ``t v_max e`` with ``t`` in [0, 1]; each condition has a
mean polynomial (degree <= 2) and a variance polynomial (degree <= 4) in ``t``
(:func:`prvo_planner.core.moments.ray_polynomials`). The ray search
(:mod:`prvo_planner.core.ray_search`) cuts each ray at the roots of its tests, found here in
closed form (quadratic, Cardano, Ferrari) and polished by a Newton step; a root missed by
rounding can only shift a boundary by rounding-level amounts because acceptance is always
re-evaluated exactly. Bernstein coefficients certify a constant sign per segment of [0, 1].

Every function is compiled by numba (``cache=True``: compiled once, then loaded from
``__pycache__``) and works on one polynomial at a time, with the operations numpy's vectorised
forms of these formulas did, in the same order: ``x ** 3`` is ``pow``, ``x ** 2`` a product, and
the Bernstein products are fused multiply-adds in the order of their terms, as OpenBLAS's
matrix product sums them.
"""

import math

from numba import njit, types
from numba.extending import intrinsic
import numpy as np

# Argument types of the kernels' signatures: arrays handed in by callers may be read-only (a
# belief's mean, broadcast views, a cached grid), and the kernels only read them.
READ_ONLY_VECTOR = types.Array(types.float64, 1, 'C', readonly=True)
READ_ONLY_ROWS = types.Array(types.float64, 2, 'C', readonly=True)
READ_ONLY_CUBE = types.Array(types.float64, 3, 'C', readonly=True)
READ_ONLY_FLAGS = types.Array(types.boolean, 1, 'C', readonly=True)
READ_ONLY_INDICES = types.Array(types.int64, 1, 'C', readonly=True)


def jit(*signature, inline='never'):
    """
    Compile a function of the core (ray search, certificate) with numba, cached where it can.

    Division by zero and the square root of a negative give inf and NaN as in numpy instead of
    raising. The cache is ``__pycache__`` beside the source, else numba's user-wide directory
    (``NUMBA_CACHE_DIR``, else ``~/.cache/numba``); where none of them can be written (a
    read-only install and home) numba refuses to cache, and the function is compiled in memory
    by every process instead. ``inline='always'`` inlines a small helper where it is called
    (numba's own inlining: no call, no reference counting of its array arguments).
    """
    def decorate(function):
        try:
            return njit(*signature, cache=True, error_model='numpy', nogil=True,
                        inline=inline)(function)
        except RuntimeError:
            # numba: 'cannot cache function ...: no locator available'.
            return njit(*signature, cache=False, error_model='numpy', nogil=True,
                        inline=inline)(function)

    return decorate


# Leading coefficients below this (relative to the largest one, on t in [0, 1]) are treated as
# zero: dropping them moves the polynomial by at most this much there, and a Newton step on the
# full polynomial (which squares a root's relative error) removes the resulting root error.
_DEGREE_TOLERANCE = 1e-7
# Roots within this distance of 0.5, i.e. within 2e-3 of [0, 1], are polished.
_POLISH_REACH = 0.5 + 2e-3
# The three angles of the trigonometric roots of a cubic: (0, 2, 4) pi / 3.
_TRISECTION = np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
_ANGLE_1, _ANGLE_2 = float(_TRISECTION[1]), float(_TRISECTION[2])

# Certificates are per segment of [0, 1]: a neighbour that rejects a whole segment of a ray
# closes it for every other neighbour, whose roots there need not be found.
SEGMENTS = 4


@intrinsic
def _fma(typingctx, a, b, c):
    """Return ``a b + c`` rounded once (LLVM's ``llvm.fma``, one instruction if there is one)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, arguments):
        return builder.fma(*arguments)

    return signature, codegen


@jit()
def _maximum(a, b):
    """``numpy.maximum`` of two floats: NaN if either is."""
    return a if a >= b or a != a else b


@jit()
def _minimum(a, b):
    """``numpy.minimum`` of two floats: NaN if either is."""
    return a if a <= b or a != a else b


@jit()
def _finite_or_nan(value):
    """Return VALUE if finite, else NaN."""
    return value if math.isfinite(value) else np.nan


@jit()
def quadratic_roots(constant, linear, quadratic):
    """
    Real roots of ``quadratic t^2 + linear t + constant``, robust to a vanishing leading term.

    Returns the two roots, NaN where there is none.
    """
    scale = _maximum(_maximum(abs(constant), abs(linear)), abs(quadratic))
    if not scale > 0.0:
        scale = 1.0
    c0, c1, c2 = constant / scale, linear / scale, quadratic / scale
    discriminant = c1 * c1 - 4.0 * c2 * c0
    root_disc = math.sqrt(discriminant) if discriminant >= 0.0 else np.nan
    # half is never a difference of close numbers; with c2 = 0 the first root is -c0/c1.
    half = -0.5 * (c1 + (root_disc if c1 >= 0.0 else -root_disc))
    if half != 0.0:
        first = c0 / half
    else:
        first = 0.0 if c2 != 0.0 else np.nan
    return _finite_or_nan(first), _finite_or_nan(half / c2)


@jit()
def _cardano_root(p, q):
    """Return the real root of ``x^3 + p x + q`` when it is the only one, and the discriminant."""
    half_q = 0.5 * q
    discriminant = half_q * half_q + math.pow(p / 3.0, 3.0)
    big = np.cbrt(-0.5 * q - math.copysign(math.sqrt(abs(discriminant)), q))
    return (big - p / (3.0 * big) if big != 0.0 else 0.0), discriminant


@jit()
def _monic_cubic_roots(b, c, d):
    """Real roots of ``t^3 + b t^2 + c t + d``, NaN for complex ones."""
    shift = -b / 3.0
    p = c - b * b / 3.0
    q = (2.0 * b * b * b / 27.0) - b * c / 3.0 + d
    single, discriminant = _cardano_root(p, q)
    if discriminant > 0.0:
        return single + shift, np.nan, np.nan
    rho = math.sqrt(_maximum(-p / 3.0, 0.0))
    cosine = -0.5 * q / math.pow(rho, 3.0) if rho > 0.0 else 0.0
    theta = math.acos(_minimum(_maximum(cosine, -1.0), 1.0)) / 3.0
    scale = 2.0 * rho
    return (scale * math.cos(theta) + shift, scale * math.cos(theta - _ANGLE_1) + shift,
            scale * math.cos(theta - _ANGLE_2) + shift)


@jit()
def _stable_quadratic_roots(linear, constant):
    """Real roots of ``t^2 + linear t + constant`` without cancellation."""
    half = -0.5 * (linear + math.copysign(math.sqrt(linear * linear - 4.0 * constant), linear))
    return half, (constant / half if half != 0.0 else 0.0)


@jit()
def _monic_quartic_roots(b, c, d, e):
    """
    Real roots of ``t^4 + b t^3 + c t^2 + d t + e`` (Ferrari), NaN for complex ones.

    The depressed quartic ``y^4 + p y^2 + q y + r`` (``t = y - b / 4``) factors as
    ``(y^2 + s y + m + p/2 - q/(2 s)) (y^2 - s y + m + p/2 + q/(2 s))`` with ``s = sqrt(2 m)``
    and ``m`` the largest root of the resolvent ``m^3 + p m^2 + (p^2/4 - r) m - q^2/8``,
    which is ``>= 0``. Where ``m`` vanishes (``q = 0``) the quartic is biquadratic instead.
    """
    shift = -0.25 * b
    b2 = b * b
    p = c - 0.375 * b2
    q = d - 0.5 * b * c + 0.125 * b2 * b
    r = e - 0.25 * b * d + 0.0625 * b2 * c - 0.01171875 * b2 * b2
    # The resolvent depressed by m = x - p/3: x^3 + P x + Q.
    p2 = p * p
    cubic_p = -p2 / 12.0 - r
    cubic_q = p * (r / 3.0 - p2 / 108.0) - 0.125 * q * q
    # One real root (Cardano) or three (the largest is the trigonometric one of angle 0).
    single, discriminant = _cardano_root(cubic_p, cubic_q)
    if discriminant > 0.0:
        largest = single
    else:
        rho = math.sqrt(_maximum(-cubic_p / 3.0, 0.0))
        cosine = -0.5 * cubic_q / (rho * rho * rho)
        largest = 2.0 * rho * math.cos(math.acos(_minimum(_maximum(cosine, -1.0), 1.0)) / 3.0)
    m = _maximum(largest - p / 3.0, 0.0)
    if m <= 1e-12 * _maximum(1.0, abs(p) + math.sqrt(abs(r))):
        # Biquadratic: y^2 is a root of z^2 + p z + r.
        first, second = _stable_quadratic_roots(p, r)
        first, second = math.sqrt(first), math.sqrt(second)
        return first + shift, second + shift, -first + shift, -second + shift
    s = math.sqrt(2.0 * m)
    offset = 0.5 * q / s if s > 0.0 else 0.0
    base = 0.5 * p + m
    first, second = _stable_quadratic_roots(s, base - offset)
    third, fourth = _stable_quadratic_roots(-s, base + offset)
    return first + shift, third + shift, second + shift, fourth + shift


@jit()
def _polished(c0, c1, c2, c3, c4, root):
    """
    Newton-polish ROOT of the quartic with coefficients C0..C4, if it is near [0, 1].

    Only roots within 2e-3 of [0, 1] are polished: the step moves a root by less than 1e-3, so
    no other root can enter (0, 1), where breakpoints matter.
    """
    if not abs(root - 0.5) <= _POLISH_REACH:
        return root
    value = c4 * root + c3
    slope = (c4 * 4.0) * root + c3 * 3.0
    value = value * root + c2
    slope = slope * root + c2 * 2.0
    value = value * root + c1
    slope = slope * root + c1 * 1.0
    value = value * root + c0
    step = value / slope
    # A large step means a flat spot (near-double root): keep the closed-form value.
    return root - step if abs(step) < 1e-3 else root


@jit()
def polynomial_roots(c0, c1, c2, c3, c4):
    """
    Real roots of a polynomial of degree <= 4 (ascending coefficients), with degree detection.

    Returns four roots, NaN-padded.
    """
    scale = _maximum(_maximum(_maximum(_maximum(abs(c0), abs(c1)), abs(c2)), abs(c3)), abs(c4))
    c0, c1, c2, c3, c4 = c0 / scale, c1 / scale, c2 / scale, c3 / scale, c4 / scale
    if abs(c4) > _DEGREE_TOLERANCE:
        roots = _monic_quartic_roots(c3 / c4, c2 / c4, c1 / c4, c0 / c4)
    elif abs(c3) > _DEGREE_TOLERANCE:
        first, second, third = _monic_cubic_roots(c2 / c3, c1 / c3, c0 / c3)
        roots = (first, second, third, np.nan)
    else:
        first, second = quadratic_roots(c0, c1, c2)
        roots = (first, second, np.nan, np.nan)
    return (_polished(c0, c1, c2, c3, c4, roots[0]), _polished(c0, c1, c2, c3, c4, roots[1]),
            _polished(c0, c1, c2, c3, c4, roots[2]), _polished(c0, c1, c2, c3, c4, roots[3]))


def _bernstein_matrix(degree):
    """Map ascending power coefficients on [0, 1] to Bernstein coefficients, (L, L)."""
    matrix = np.zeros((degree + 1, degree + 1))
    for power in range(degree + 1):
        for index in range(power, degree + 1):
            matrix[power, index] = math.comb(index, power) / math.comb(degree, power)
    return matrix


_BERNSTEIN = {degree: _bernstein_matrix(degree) for degree in (2, 4)}
# Bernstein coefficient i of a quartic on [0, 1] is row i of this times its coefficients.
_QUARTIC_BERNSTEIN = np.ascontiguousarray(_BERNSTEIN[4].T)


def _segment_bernstein_matrix(degree, segments):
    """
    Map ascending power coefficients to Bernstein coefficients on each of equal segments.

    On segment ``j``, ``[a, b] = [j, j + 1] / segments``, substituting ``t = a + (b - a) s``
    gives power coefficients in ``s`` on [0, 1], whose Bernstein coefficients bound the
    polynomial there. Returns shape (segments (degree + 1), degree + 1).
    """
    blocks = []
    for segment in range(segments):
        start, width = segment / segments, 1.0 / segments
        substitution = np.zeros((degree + 1, degree + 1))
        for power in range(degree + 1):
            for order in range(power + 1):
                substitution[order, power] = (math.comb(power, order) * start ** (power - order)
                                              * width ** order)
        blocks.append(_BERNSTEIN[degree].T @ substitution)
    return np.concatenate(blocks)


_SEGMENT_BERNSTEIN_2 = _segment_bernstein_matrix(2, SEGMENTS)
_SEGMENT_BERNSTEIN_4 = _segment_bernstein_matrix(4, SEGMENTS)


@jit()
def bernstein_may_vanish(variances, row):
    """
    Whether the quartic in column ROW of coefficient-major VARIANCES (5, K) is not certified > 0.

    Its smallest Bernstein coefficient on [0, 1], a lower bound there, is ``<= 0`` (False where
    one is NaN, as numpy's minimum is then).
    """
    matrix = _QUARTIC_BERNSTEIN
    smallest = np.inf
    for index in range(5):
        value = matrix[index, 0] * variances[0, row]
        for power in range(1, 5):
            value = _fma(matrix[index, power], variances[power, row], value)
        if value != value:
            return False
        smallest = min(smallest, value)
    return smallest <= 0.0


@jit()
def segment_certificates(coefficients, first, counts):
    """
    Certify a constant sign on each of the ``SEGMENTS`` equal segments of [0, 1].

    A polynomial is a convex combination of its Bernstein coefficients on a segment, so all of
    them ``>= 0`` proves ``p >= 0`` there and all ``< 0`` proves ``p < 0``.

    Parameters
    ----------
    coefficients : numpy.ndarray
        Ascending coefficients, coefficient-major: shape (L, K') with L = 3 or 5.
    first : int
        The first of the K columns certified.
    counts : numpy.ndarray
        Filled with how many of each segment's L Bernstein coefficients are ``>= 0``: L
        certifies ``p >= 0``, 0 certifies ``p < 0``; shape (SEGMENTS, K), uint8.

    """
    count = counts.shape[1]
    if coefficients.shape[0] == 5:
        matrix = _SEGMENT_BERNSTEIN_4
        for segment in range(SEGMENTS):
            for row in range(count):
                column = first + row
                c0, c1, c2 = (coefficients[0, column], coefficients[1, column],
                              coefficients[2, column])
                c3, c4 = coefficients[3, column], coefficients[4, column]
                nonnegative = 0
                for index in range(5):
                    weights = segment * 5 + index
                    value = _fma(matrix[weights, 4], c4, _fma(
                        matrix[weights, 3], c3, _fma(matrix[weights, 2], c2, _fma(
                            matrix[weights, 1], c1, matrix[weights, 0] * c0))))
                    nonnegative += value >= 0.0
                counts[segment, row] = nonnegative
    else:
        matrix = _SEGMENT_BERNSTEIN_2
        for segment in range(SEGMENTS):
            for row in range(count):
                column = first + row
                c0, c1, c2 = (coefficients[0, column], coefficients[1, column],
                              coefficients[2, column])
                nonnegative = 0
                for index in range(3):
                    weights = segment * 3 + index
                    value = _fma(matrix[weights, 2], c2, _fma(
                        matrix[weights, 1], c1, matrix[weights, 0] * c0))
                    nonnegative += value >= 0.0
                counts[segment, row] = nonnegative


@jit()
def _horner(coefficients, count, t):
    """Evaluate the first COUNT ascending COEFFICIENTS at T by Horner's rule."""
    value = coefficients[count - 1]
    for power in range(count - 2, -1, -1):
        value = value * t + coefficients[power]
    return value


@jit()
def taylor_quadratics(means, variances, margins, preferred, out):
    """
    Build the paper's quadratic surrogate ``mean(t) - k T(t)`` (docs/method.md, section 6).

    ``T`` is the second-order Taylor expansion of ``sigma = sqrt(variance)`` around ``t*``, the
    point of ``{t in [0, 1] : mean(t) >= 0}`` closest to the preferred ``t`` on the ray (the
    preferred ``t`` itself when that set is empty).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Coefficient-major, shapes (3, K) and (5, K).
    margins : numpy.ndarray
        ``k`` per column, shape (K,).
    preferred : numpy.ndarray
        Preferred ``t`` per column, shape (K,).
    out : numpy.ndarray
        The surrogates' coefficients, coefficient-major, shape (3, K), filled.

    """
    candidates = np.empty(5)
    mean = np.empty(3)
    variance_poly = np.empty(5)
    first = np.empty(4)
    second = np.empty(3)
    for row in range(means.shape[1]):
        for power in range(3):
            mean[power] = means[power, row]
        for power in range(5):
            variance_poly[power] = variances[power, row]
        candidates[0] = _minimum(_maximum(preferred[row], 0.0), 1.0)
        low, high = quadratic_roots(mean[0], mean[1], mean[2])
        candidates[1] = min(max(0.0 if low != low else low, 0.0), 1.0)
        candidates[2] = min(max(0.0 if high != high else high, 0.0), 1.0)
        candidates[3] = 0.0
        candidates[4] = 1.0
        # The first candidate nearest the preferred t where the mean is >= 0.
        centre, nearest = candidates[0], np.inf
        for index in range(5):
            if _horner(mean, 3, candidates[index]) >= 0.0:
                distance = abs(candidates[index] - candidates[0])
                if distance < nearest:
                    centre, nearest = candidates[index], distance
        for power in range(4):
            first[power] = variance_poly[power + 1] * (power + 1.0)
        for power in range(3):
            second[power] = first[power + 1] * (power + 1.0)
        sigma = math.sqrt(_maximum(_horner(variance_poly, 5, centre), 0.0))
        slope_var = _horner(first, 4, centre)
        curve_var = _horner(second, 3, centre)
        if sigma > 0.0:
            slope = slope_var / (2.0 * sigma)
            curve = curve_var / (2.0 * sigma) - slope_var * slope_var / (
                4.0 * math.pow(sigma, 3.0))
        else:
            slope = curve = 0.0
        k = margins[row]
        out[0, row] = mean[0] - k * (sigma - slope * centre + 0.5 * curve * (centre * centre))
        out[1, row] = mean[1] - k * (slope - curve * centre)
        out[2, row] = mean[2] - k * 0.5 * curve
