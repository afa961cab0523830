"""
Closed-form moments of the RVO condition and of the receding, horizon and reach conditions.

With ``z = (r_x, r_y, u_x, u_y) ~ N(mu, S)`` every condition of docs/method.md is a quadratic
form ``z'Xz`` or, for ``f``, ``q^2 - R^2 p`` with quadratic forms ``q = r x u = z'Az`` and
``p = |u|^2 = z'Bz``. Joint cumulants of Gaussian quadratic forms have a closed form (from the
cumulant generating function ``-1/2 log det(I - 2 M S) + mu' (I - 2 M S)^-1 M mu``):

    k(z'X1 z, ..., z'Xn z) = 2^(n-1) [ (1/n) sum_perm tr(X1 S ... Xn S)
                                        + sum_perm mu' X1 S ... S Xn mu ]

so ``E[f] = k2(q) + k1(q)^2 - R^2 E[p]`` and

    Var[f] = k4 + 4 k3 k1 + 2 k2^2 + 4 k2 k1^2 - 2 R^2 (k(q,q,p) + 2 k1 k(q,p)) + R^4 Var[p].

Every term is a trace (independent of the mean) plus a quadratic form ``mu'Xmu``.

For the planner, ``E`` is a quadratic and ``Var`` a quartic polynomial in the commanded
velocity ``v_c`` (``mu_w = v_c / rho + mu_w(0)``, ``1 / rho = 2`` for RVO). Their coefficients
are recovered exactly (to rounding) by evaluating the closed form on a 5 x 5 Chebyshev grid over
``[-v_max, v_max]^2`` and applying a fixed least-squares inverse of the bivariate quartic
Vandermonde matrix (a well-conditioned, full-rank 25 x 15 system); restricted to a ray
``v_c = t v_max e`` they become polynomials in ``t``, sums of their coefficients times the
direction's monomials (compiled: :func:`.ray_search.ray_links`). This costs a few hundred
closed-form evaluations per plan, independent of the number of directions.

The closed forms and the fit are compiled by numba (:mod:`.moment_kernels`, loaded on the
first call of :func:`condition_moments`, :func:`bivariate_polynomials` or :func:`reach_weights`);
this module lays out their arguments.
"""

import math

import numpy as np

# The reach condition h3 (docs/method.md, section 7) trades |r|^2 against tau^2 |w|^2 by a
# weight eps in (0, 1), chosen per neighbour from its mean distance d as 1 - R / d (where h3
# is exact), within these bounds.
REACH_WEIGHT_BOUNDS = (0.05, 0.95)


def reach_weights(origin, combined_radius):
    """
    Return the weight ``eps`` of each neighbour's reach condition ``h3``, shape (N,).

    ORIGIN (N, 4) is the mean of ``z`` (its first two components the relative position's),
    COMBINED_RADIUS (N,) ``R``: ``1 - R / |mu_r|`` within `REACH_WEIGHT_BOUNDS` (compiled:
    :func:`.moment_kernels.reach_weights`, which :func:`condition_moments` applies itself).
    """
    from .moment_kernels import reach_weights as weights

    return weights(np.ascontiguousarray(origin, dtype=np.float64),
                   np.ascontiguousarray(combined_radius, dtype=np.float64))


def rvo_moments(mean, cov, radius):
    """
    Exact ``E[f]`` and ``Var[f]`` of ``f = (r x u)^2 - R^2 |u|^2`` for Gaussian ``z = (r, u)``.

    Parameters
    ----------
    mean : array_like
        Mean of ``z = (r_x, r_y, u_x, u_y)``, shape (..., 4).
    cov : array_like
        Covariance of ``z``, shape (..., 4, 4), symmetric PSD (cross terms allowed).
    radius : float or array_like
        Combined radius ``R``, broadcastable to shape (...).

    Returns
    -------
    expectation : numpy.ndarray
        ``E[f]``, shape (...).
    variance : numpy.ndarray
        ``Var[f]``, shape (...).

    """
    mean = np.asarray(mean, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if mean.shape[-1:] != (4,) or cov.shape[-2:] != (4, 4):
        raise ValueError(f'mean must have shape (..., 4) and cov (..., 4, 4), got '
                         f'{mean.shape} and {cov.shape}')
    shape = np.broadcast_shapes(mean.shape[:-1], cov.shape[:-2])
    count = math.prod(shape)
    # f's moments are condition_moments' first column at a zero command (lead 0: the mean of
    # z is MEAN itself).
    means, variances = condition_moments(
        np.broadcast_to(mean, shape + (4,)).reshape(count, 4),
        np.broadcast_to(cov, shape + (4, 4)).reshape(count, 4, 4),
        np.broadcast_to(np.asarray(radius, dtype=float), shape).reshape(count),
        np.zeros((1, 2)), math.inf, False, 0.0)
    return means[:, 0, 0].reshape(shape), variances[:, 0, 0].reshape(shape)


def condition_moments(origin, cov, combined_radius, velocities, time_horizon, receding_gate,
                      lead=2.0):
    """
    Mean and variance of every condition at given commanded velocities.

    The conditions are, in order: ``f``; ``g`` if ``receding_gate``; ``h1``, ``h2`` and
    ``h3`` if ``time_horizon`` is finite (docs/method.md, sections 3 and 7).

    Parameters
    ----------
    origin : numpy.ndarray
        Mean of ``z`` at ``v_c = 0``, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z``, shape (N, 4, 4).
    combined_radius : numpy.ndarray
        ``R`` per neighbour, shape (N,).
    velocities : numpy.ndarray
        Commanded velocities ``v_c``, shape (P, 2) or (N, P, 2).
    time_horizon : float or numpy.ndarray
        ``tau`` (``inf`` drops ``h1``, ``h2`` and ``h3``), or one per neighbour, shape (N,),
        all finite or all infinite.
    receding_gate : bool
        Whether ``g`` is a condition.
    lead : float or numpy.ndarray
        ``1 / rho``, the factor of the command in the relative velocity, per neighbour,
        shape (N,) (2 for reciprocal avoidance).

    Returns
    -------
    means, variances : numpy.ndarray
        Shape (N, P, C) each.

    """
    from .moment_kernels import condition_moments as moments

    # Compiled (moment_kernels): the matrices and traces per neighbour, the cumulants per point.
    return moments(*_kernel_arguments(origin, cov, combined_radius, velocities, time_horizon,
                                      receding_gate, lead))


def condition_margins(origin, cov, combined_radius, velocities, time_horizon, receding_gate,
                      lead, enabled):
    """
    Return the margin ``k`` met at commanded velocities against each neighbour, (P, N).

    The arguments as for :func:`condition_moments`; ENABLED (N,) whether each neighbour's gate
    counts. Compiled (:func:`.moment_kernels.condition_margins`: the moments and the margins in
    one call).
    """
    from .moment_kernels import condition_margins as margins

    return margins(*_kernel_arguments(origin, cov, combined_radius, velocities, time_horizon,
                                      receding_gate, lead),
                   np.ascontiguousarray(enabled, dtype=bool))


def _per_neighbour(value, count):
    """Return VALUE, one per neighbour (COUNT,) or shared (1,), as a contiguous float array."""
    if isinstance(value, (int, float)):
        return np.array([value], dtype=np.float64)
    value = np.asarray(value, dtype=np.float64)
    if value.ndim == 0:
        return value.reshape(1)
    if value.shape == (count,):
        return np.ascontiguousarray(value)
    return np.ascontiguousarray(np.broadcast_to(value, (count,)))


def _kernel_arguments(origin, cov, combined_radius, velocities, time_horizon, receding_gate,
                      lead):
    """Return the arguments of the moments' kernels: contiguous arrays, whether tau is finite."""
    count = origin.shape[0]
    horizon = _per_neighbour(time_horizon, count)
    finite = (math.isfinite(time_horizon) if isinstance(time_horizon, (int, float))
              else bool(np.isfinite(horizon).all()))
    velocities = np.asarray(velocities, dtype=np.float64)
    if velocities.ndim == 2:
        # Shared by every neighbour: the kernels read it as (1, P, 2).
        velocities = velocities[None]
    return (np.ascontiguousarray(origin, dtype=np.float64),
            np.ascontiguousarray(cov, dtype=np.float64),
            np.ascontiguousarray(combined_radius, dtype=np.float64),
            np.ascontiguousarray(velocities), horizon, _per_neighbour(lead, count),
            bool(receding_gate), finite)


def _monomial_exponents():
    """Exponents ``(i, j)`` of ``x^i y^j``, total degree <= 4, grouped by degree."""
    return np.array([(degree - j, j) for degree in range(5) for j in range(degree + 1)])


_EXPONENTS = _monomial_exponents()
# Chebyshev-Lobatto nodes: the 5 x 5 tensor grid is unisolvent for bivariate quartics.
NODES_1D = np.cos(np.pi * np.arange(5) / 4.0)
NODES = np.stack(np.meshgrid(NODES_1D, NODES_1D, indexing='ij'), axis=-1).reshape(-1, 2)
_FIT = np.ascontiguousarray(np.linalg.pinv(np.prod(NODES[:, None, :] ** _EXPONENTS[None, :, :],
                                                   axis=-1)))


def ray_polynomials(origin, cov, combined_radius, directions, scale, time_horizon,
                    receding_gate, lead=2.0):
    """
    Mean and variance polynomials in ``t`` of every condition on every (neighbour, ray) pair.

    Along a ray the commanded velocity is ``v_c = t scale e`` with ``t`` in [0, 1].

    Parameters
    ----------
    origin, cov, combined_radius, time_horizon, receding_gate, lead
        As for :func:`condition_moments`.
    directions : numpy.ndarray
        Unit directions ``e``, shape (M, 2).
    scale : float
        ``v_max``.

    Returns
    -------
    means : numpy.ndarray
        Shape (N, M, C, 3), laid out coefficient-major in memory.
    variances : numpy.ndarray
        Shape (N, M, C, 5), laid out coefficient-major in memory.

    """
    from .ray_search import ray_links

    mean_fit, variance_fit = bivariate_polynomials(origin, cov, combined_radius,
                                                   scale * NODES, time_horizon, receding_gate,
                                                   lead)
    count, conditions = mean_fit.shape[:2]
    rays = directions.shape[0]
    # Compiled (ray_search.ray_links): (L, N M, C) per polynomial, viewed as (N, M, C, L).
    means, variances = ray_links(
        mean_fit.swapaxes(1, 2), variance_fit.swapaxes(1, 2),
        np.ascontiguousarray(directions, dtype=np.float64), np.array([count]), np.array([rays]),
        np.zeros((1, conditions)), np.zeros(count, dtype=bool))[:2]
    return tuple(polynomials.reshape(length, count, rays, conditions).transpose(1, 2, 3, 0)
                 for polynomials, length in ((means, 3), (variances, 5)))


def bivariate_polynomials(origin, cov, combined_radius, node_velocities, time_horizon,
                          receding_gate, lead):
    """
    Coefficients of the mean (quadratic) and variance (quartic) of every condition in ``v_c``.

    The coefficients are of the monomials ``(v_x / v_max)^i (v_y / v_max)^j``, fitted on the
    Chebyshev grid ``node_velocities`` = ``v_max`` times the unit grid. Every neighbour's
    coefficients come from its own rows alone, so neighbours of several plans can be stacked.

    Parameters
    ----------
    origin, cov, combined_radius, time_horizon, receding_gate, lead
        As for :func:`condition_moments`.
    node_velocities : numpy.ndarray
        The grid at each neighbour's plan's ``v_max``, shape (25, 2) or (N, 25, 2).

    Returns
    -------
    means : numpy.ndarray
        Shape (N, C, 6).
    variances : numpy.ndarray
        Shape (N, C, 15).

    """
    from .moment_kernels import condition_polynomials

    # Compiled (moment_kernels): the moments on the grid and the fit, in one call.
    means, variances = condition_polynomials(
        *_kernel_arguments(origin, cov, combined_radius, node_velocities, time_horizon,
                           receding_gate, lead), _FIT)
    return means.swapaxes(-1, -2), variances.swapaxes(-1, -2)
