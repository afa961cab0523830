"""Gaussian beliefs over disk robots and the validation shared by the core."""

from dataclasses import dataclass
import math

import numpy as np

# Eigenvalues down to -_PSD_TOLERANCE * scale are rounding, not a modelling error.
_PSD_TOLERANCE = 1e-9
# Arrays up to this many entries are checked for finiteness without numpy.
_SMALL = 16


def as_finite_array(value, shape, field):
    """
    Convert ``value`` to a read-only float array of a given shape.

    Parameters
    ----------
    value : array_like
        Anything ``np.asarray`` accepts.
    shape : tuple of int
        Required shape.
    field : str
        Name used in the error message.

    Returns
    -------
    numpy.ndarray
        A float64 copy with the write flag cleared.

    Raises
    ------
    ValueError
        If the shape is wrong or an entry is NaN or infinite.

    """
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f'{field} must be a float array of shape {shape}, '
                         f'got {value!r}') from error
    if array.shape != tuple(shape):
        raise ValueError(f'{field} must have shape {tuple(shape)}, got shape {array.shape}: '
                         f'{value!r}')
    # Beliefs and plans check a few small arrays on every planning cycle: up to _SMALL entries
    # one C loop over Python floats costs less than numpy's dispatch of two calls.
    if not (all(map(math.isfinite, array.ravel().tolist())) if array.size <= _SMALL
            else np.isfinite(array).all()):
        raise ValueError(f'{field} must be finite, got {array.tolist()!r}')
    array.setflags(write=False)
    return array


def as_covariance(value, size, field):
    """
    Convert ``value`` to a symmetric positive semi-definite covariance.

    Rounding-level asymmetry is averaged out and rounding-level negative eigenvalues are clipped
    to zero; anything larger is rejected.

    Parameters
    ----------
    value : array_like
        Matrix of shape (size, size).
    size : int
        Dimension.
    field : str
        Name used in the error message.

    Returns
    -------
    numpy.ndarray
        Read-only float64 array of shape (size, size).

    Raises
    ------
    ValueError
        If the matrix has the wrong shape, is not finite, not symmetric, or not PSD.

    """
    matrix = as_finite_array(value, (size, size), field)
    scale = max(1.0, float(np.abs(matrix).max()))
    if np.abs(matrix - matrix.T).max() > _PSD_TOLERANCE * scale:
        raise ValueError(f'{field} must be symmetric, got {matrix.tolist()!r}')
    matrix = matrix + matrix.T
    matrix *= 0.5
    try:
        # Positive definite (the usual case): nothing to clip, and a Cholesky factorisation
        # costs less than an eigendecomposition.
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        pass
    else:
        matrix.setflags(write=False)
        return matrix
    eigenvalues, eigenvectors = np.linalg.eigh(matrix)
    if eigenvalues[0] < -_PSD_TOLERANCE * scale:
        raise ValueError(f'{field} must be positive semi-definite (smallest eigenvalue '
                         f'{eigenvalues[0]:.3g}), got {matrix.tolist()!r}')
    if eigenvalues[0] < 0.0:
        matrix = (eigenvectors * np.maximum(eigenvalues, 0.0)) @ eigenvectors.T
        matrix = 0.5 * (matrix + matrix.T)
    matrix.setflags(write=False)
    return matrix


@dataclass(frozen=True)
class AgentBelief:
    """
    Gaussian belief over one disk robot's state ``[x, y, vx, vy]`` in the world frame.

    Attributes
    ----------
    position : numpy.ndarray
        Mean position, shape (2,), metres.
    velocity : numpy.ndarray
        Mean velocity, shape (2,), m/s.
    covariance : numpy.ndarray
        Covariance over ``[x, y, vx, vy]``, shape (4, 4), cross terms allowed.
    radius : float
        Disk radius, metres, > 0.
    avoidance_share : float
        The share of a pair's avoidance this robot takes itself, in [0, 1): 0.5 for a
        reciprocating planner, 0 for a robot that does not avoid (docs/method.md, section 11).
        Only neighbours' shares are used.

    """

    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    radius: float
    avoidance_share: float = 0.5

    def __post_init__(self):
        object.__setattr__(self, 'position',
                           as_finite_array(self.position, (2,), 'AgentBelief.position'))
        object.__setattr__(self, 'velocity',
                           as_finite_array(self.velocity, (2,), 'AgentBelief.velocity'))
        object.__setattr__(self, 'covariance',
                           as_covariance(self.covariance, 4, 'AgentBelief.covariance'))
        if isinstance(self.radius, (int, float)) and math.isfinite(self.radius):
            # The usual case, without an array round trip.
            radius = float(self.radius)
        else:
            radius = float(as_finite_array(self.radius, (), 'AgentBelief.radius'))
        if radius <= 0.0:
            raise ValueError(f'AgentBelief.radius must be > 0, got {radius!r}')
        object.__setattr__(self, 'radius', radius)
        object.__setattr__(self, 'avoidance_share', validated_share(
            self.avoidance_share, 'AgentBelief.avoidance_share'))


def validated_share(value, field):
    """
    Return ``value`` as a share of the avoidance: a float in [0, 1).

    Raises
    ------
    ValueError
        If it is not a number in [0, 1), naming ``field``.

    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f'{field} must be a number in [0, 1), got {value!r}')
    share = float(value)
    if not 0.0 <= share < 1.0:
        raise ValueError(f'{field} must be in [0, 1), got {share!r}')
    return share
