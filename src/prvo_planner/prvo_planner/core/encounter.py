"""
The neighbours of one plan as relative Gaussians, the candidate directions, and the conditions.

``build_encounter`` turns beliefs into the mean and covariance of ``z = (r, w)`` per neighbour
(docs/method.md, sections 2 and 11); ``condition_layout`` says which of the alternatives
``f``, ``g``, ``h1 and h2`` each neighbour is judged by; ``model_moments`` gives the covariance and
radius each model plans with.
"""

from dataclasses import dataclass
import functools
import math

import numpy as np

from .probability import confidence_ellipse_scale, eta_from_k


@dataclass(frozen=True)
class Encounter:
    """
    The neighbours a plan considers, as relative Gaussians (docs/method.md, sections 2, 11).

    With ``rho = 1 - a_j`` the ego's share of the avoidance against a neighbour of share
    ``a_j``, the relative velocity is ``w = (v_x - (1 - rho) v_i) / rho - v_j``: ``u`` of RVO for
    ``rho = 1/2``, the plain relative velocity for ``rho = 1``.

    Attributes
    ----------
    origin : numpy.ndarray
        Mean of ``z = (r, w)`` at zero command, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z`` (with ``S_a / rho^2`` in the velocity block), shape (N, 4, 4).
    lead : numpy.ndarray
        ``1 / rho``, the factor of the command in ``w``, shape (N,).
    combined_radius : numpy.ndarray
        ``R = R_i + R_j + margin``, shape (N,).
    overlapping : numpy.ndarray
        Whether the mean centres are closer than ``R``, shape (N,).
    margin : float
        Per-neighbour ``k`` for ``f`` and ``g``.
    horizon_margin : float
        Per-neighbour ``k'`` for each of ``h1`` and ``h2``.
    eta : float
        Per-neighbour probability in force.

    """

    origin: np.ndarray
    cov: np.ndarray
    lead: np.ndarray
    combined_radius: np.ndarray
    overlapping: np.ndarray
    margin: float
    horizon_margin: float
    eta: float


def build_encounter(ego, neighbours, config):
    """
    Select the neighbours within ``neighbor_distance`` and form their relative Gaussians.

    The distance is between the mean disk surfaces: ``|p_i - p_j| - R_i - R_j``. A neighbour
    that takes a share of the avoidance and could touch the ego within ``config.guard_time``
    has a second row after all the others: share 0 over that time (``PlannerConfig.guard_time``).

    Parameters
    ----------
    ego : AgentBelief
        The planning robot.
    neighbours : sequence of AgentBelief
        Other robots.
    config : PlannerConfig
        Planner parameters.

    Returns
    -------
    Encounter
        The selected neighbours (possibly none), then their guard rows.

    """
    from .ray_search import relative_gaussians

    # Compiled (ray_search.relative_gaussians): the selection, the guard rows, the Gaussians.
    origin, cov, lead, combined_radius, overlapping, _ = relative_gaussians(
        ego.position, ego.velocity, ego.covariance, float(ego.radius),
        np.array([belief.position for belief in neighbours]).reshape(-1, 2),
        np.array([belief.velocity for belief in neighbours]).reshape(-1, 2),
        np.array([belief.covariance for belief in neighbours]).reshape(-1, 4, 4),
        np.array([belief.radius for belief in neighbours], dtype=np.float64),
        np.array([belief.avoidance_share for belief in neighbours], dtype=np.float64),
        config.actuation_cov, float(config.neighbor_distance), float(config.guard_time),
        float(config.max_speed), float(config.time_horizon), float(config.safety_margin))
    margin, horizon_margin, eta = _margins(
        config.effective_k, origin.shape[0] if config.risk == 'joint' else 0)
    return Encounter(
        origin=origin, cov=cov, lead=lead, combined_radius=combined_radius,
        overlapping=overlapping, margin=margin, horizon_margin=horizon_margin, eta=eta)


@functools.lru_cache(maxsize=256)
def _margins(k, joint_count):
    """
    Return the margin, the horizon margin and the probability per neighbour (cached).

    ``k`` is the configuration's margin; ``joint_count`` the number of rows that share the
    risk (``risk='joint'``), 0 for none.
    """
    margin = k
    if joint_count > 0:
        # 1 - eta_j = (1 - eta) / n with 1 - eta = 1 / (1 + k^2), written in k to stay finite;
        # a guard row is one more condition to share the risk with.
        margin = math.sqrt((1.0 + margin ** 2) * joint_count - 1.0)
    # k' = sqrt((1 + eta) / (1 - eta)) with eta = k^2 / (1 + k^2).
    return margin, math.sqrt(1.0 + 2.0 * margin ** 2), eta_from_k(margin)


@functools.lru_cache(maxsize=16)
def _headings(count, seed):
    """``count`` evenly spaced unit headings, rotated by a random offset when seeded (M, 2)."""
    offset = 0.0
    if seed is not None:
        offset = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi / count)
    if count % 4 == 0:
        # A quarter turned by exact quarter turns: opposite and perpendicular headings are
        # exactly so (sin(pi) is 1.2e-16, not 0), and two robots facing each other see mirror
        # images whatever rounding the machine's BLAS kernels bring.
        quarter = offset + 2.0 * np.pi * np.arange(count // 4) / count
        x, y = np.cos(quarter), np.sin(quarter)
        directions = np.stack([np.concatenate([x, -y, -x, y]),
                               np.concatenate([y, x, -y, -x])], axis=1) + 0.0
    else:
        headings = offset + 2.0 * np.pi * np.arange(count) / count
        directions = np.stack([np.cos(headings), np.sin(headings)], axis=1)
    # Shared between calls: read-only so that no caller can alter the cached value.
    directions.flags.writeable = False
    return directions


def candidate_directions(ego, v_pref, config):
    """
    Return unit candidate directions: ``v_pref``'s, the current velocity's, ``M`` headings.

    Parameters
    ----------
    ego : AgentBelief
        Supplies the current (mean) velocity.
    v_pref : numpy.ndarray
        Preferred velocity, shape (2,).
    config : PlannerConfig
        ``num_directions`` and ``seed`` (a seed rotates the headings by a random offset).

    Returns
    -------
    numpy.ndarray
        Shape (M', 2) with M' in [M, M + 2].

    """
    directions = [_headings(config.num_directions, config.seed)]
    for vector in (ego.velocity, v_pref):
        norm = math.hypot(vector[0], vector[1])
        if norm > 1e-9:
            directions.insert(0, (vector / norm)[None, :])
    return np.concatenate(directions, axis=0)


@dataclass(frozen=True)
class ConditionLayout:
    """
    Which conditions each neighbour has, in the column order of ``condition_moments``.

    Attributes
    ----------
    has_receding : bool
        A ``g`` column exists (index 1).
    has_horizon : bool
        ``h1``, ``h2`` and ``h3`` columns exist (the last three).
    receding_enabled : numpy.ndarray
        Per neighbour, whether ``g`` is accepted, shape (N,).

    """

    has_receding: bool
    has_horizon: bool
    receding_enabled: np.ndarray

    def margins(self, encounter):
        """Return the ``k`` of each condition column (``k'`` for ``h1``, ``h2``), shape (C,)."""
        return np.array([encounter.margin] * (1 + self.has_receding)
                        + [encounter.horizon_margin, encounter.horizon_margin,
                           encounter.margin] * self.has_horizon)


def condition_layout(encounter, config):
    """Conditions for an encounter: ``g`` is always on for overlapping neighbours (f < 0)."""
    enabled = np.full(encounter.overlapping.shape, config.receding_gate) | encounter.overlapping
    return ConditionLayout(has_receding=bool(enabled.any()),
                           has_horizon=math.isfinite(config.time_horizon),
                           receding_enabled=enabled)


def model_moments(encounter, config):
    """Covariance and radius the model plans with, and whether it is noise-free."""
    if config.model in ('prvo', 'mc'):
        # Exactly known beliefs make every variance zero: the means alone decide.
        return encounter.cov, encounter.combined_radius, not encounter.cov.any()
    radius = encounter.combined_radius
    if config.model == 'inflate':
        position_spread = np.linalg.eigvalsh(encounter.cov[:, :2, :2])[:, -1]
        confidence = confidence_ellipse_scale(encounter.margin)
        radius = radius + confidence * np.sqrt(np.maximum(position_spread, 0.0))
    return np.zeros_like(encounter.cov), radius, True
