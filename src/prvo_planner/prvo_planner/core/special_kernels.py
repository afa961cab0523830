"""
The normal distribution's special functions for compiled code: ``Phi`` and ``erfcx``.

numba cannot call scipy's ufuncs (:mod:`.special`), so the kernels of the certificate
(:mod:`.certificate_kernels`) and of the walls (:mod:`.wall_kernels`) call these scalar
functions, compiled into each kernel that calls them. Neither is compiled on import: a
process loads them with the first kernel that uses them.
"""

import math

from .ray_solver import _fma, jit

_SQRT_HALF = math.sqrt(0.5)
_INVERSE_SQRT_PI = 1.0 / math.sqrt(math.pi)
# Below this erfc(x) is a normal float (erfc(26) = 5.7e-296) and exp(x^2) finite; above it
# the continued fraction converges to the last bit within _FRACTION_TERMS terms.
_ERFC_LIMIT = 26.0
_FRACTION_TERMS = 40


@jit()
def ndtr(x):
    """
    Return ``Phi(x)``, the standard normal distribution function, NaN for NaN.

    Near 0 as ``1/2 + erf(x / sqrt 2) / 2``, elsewhere from ``erfc`` of ``|x| / sqrt 2``, whose
    relative error stays at the C library's in either tail.
    """
    scaled = x * _SQRT_HALF
    size = abs(scaled)
    if size < _SQRT_HALF:
        return 0.5 + 0.5 * math.erf(scaled)
    tail = 0.5 * math.erfc(size)
    return 1.0 - tail if scaled > 0.0 else tail


@jit()
def erfcx(x):
    """
    Return ``erfcx(x) = exp(x^2) erfc(x)`` for ``x >= 0`` (NaN for NaN), to a few ulps.

    Up to 26 as the product itself, with ``x^2`` split exactly into ``hi + lo`` (a fused
    multiply-add gives ``lo``): ``exp(x^2) = exp(hi) (1 + lo)`` to the last bit, where
    ``exp(hi)`` alone would carry the rounding of ``x^2``, a relative error of up to
    ``x^2 2^-53``. Beyond, Laplace's continued fraction
    ``1 / (sqrt(pi) (x + (1/2) / (x + 1 / (x + (3/2) / (x + ...)))))``, evaluated from its
    40th term back; at ``x >= 26`` its terms after the first few change nothing.
    """
    if x < _ERFC_LIMIT:
        high = x * x
        low = _fma(x, x, -high)
        return math.exp(high) * math.erfc(x) * (1.0 + low)
    tail = x
    for term in range(_FRACTION_TERMS, 0, -1):
        tail = x + 0.5 * term / tail
    return _INVERSE_SQRT_PI / tail
