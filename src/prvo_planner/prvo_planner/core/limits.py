"""
What a robot can command next: reachable speeds and trackable velocities.

Reachable: under an acceleration limit; trackable: by a differential-drive robot. On a
candidate ray ``s e`` (``s >= 0``) both restrictions are one interval of speeds:

* reachable: ``|s e - v_now| <= a_max dt`` is a chord of a disc,
  ``s in [e.v_now - sqrt(D), e.v_now + sqrt(D)]`` with ``D = (e.v_now)^2 - |v_now|^2 +
  (a_max dt)^2`` (empty when ``D < 0``);
* trackable: ``s in [0, s_max(angle(e) - heading)]``, the largest speed whose tracking error
  stays within the bound (``prvo_planner.tracking`` tabulates it).

The planner intersects each ray's feasible intervals with this one, so the exact solver is
unchanged; when nothing is left anywhere its fallback ranks the reachable candidates only.
"""

from dataclasses import dataclass
import math

import numpy as np

from .choice import choice_costs

# Extra candidate directions spread over the reachable disc: with a small disc few of the evenly
# spaced headings cross it.
REACHABLE_DIRECTIONS = 9
# Speeds tried on each ray's reachable interval when no velocity is feasible.
_FALLBACK_FRACTIONS = np.linspace(0.0, 1.0, 9)
# The approach limit takes the gap at its mean less this many stds of the relative position
# along the line between the robots (about 98% one-sided): what each robot sees of a gap differs
# by the noise of both estimates.
APPROACH_STDS = 2.0


@dataclass(frozen=True)
class VelocityLimits:
    """
    The velocities one plan may choose from.

    Attributes
    ----------
    current : numpy.ndarray or None
        ``v_now`` (2,), the command in force; None without an acceleration limit.
    max_change : float
        ``a_max dt``, how far the next command may be from ``current`` [m/s].
    heading : float or None
        The robot's yaw [rad] for a differential-drive robot; None for a holonomic one.
    trackable_speed : callable or None
        Relative angles (array, rad) -> largest trackable speeds [m/s]; with ``heading``.

    """

    current: np.ndarray | None = None
    max_change: float = math.inf
    heading: float | None = None
    trackable_speed: object = None

    def __post_init__(self):
        if self.current is not None:
            current = np.asarray(self.current, dtype=float)
            if current.shape != (2,) or not np.all(np.isfinite(current)):
                raise ValueError(f'VelocityLimits.current must be finite (2,), got '
                                 f'{self.current!r}')
            object.__setattr__(self, 'current', current)
            if not self.max_change >= 0.0:
                raise ValueError(f'VelocityLimits.max_change must be >= 0, got '
                                 f'{self.max_change!r}')
        if (self.heading is None) != (self.trackable_speed is None):
            raise ValueError('VelocityLimits.heading and trackable_speed go together')

    @property
    def accelerating(self):
        """Whether the acceleration limit restricts anything."""
        return self.current is not None and math.isfinite(self.max_change)

    def extra_directions(self):
        """Return unit directions (REACHABLE_DIRECTIONS, 2) across the reachable disc (or none)."""
        if not self.accelerating:
            return np.zeros((0, 2))
        centre = math.atan2(self.current[1], self.current[0])
        norm = math.hypot(self.current[0], self.current[1])
        half_width = (math.asin(self.max_change / norm) if norm > self.max_change
                      else math.pi)
        angles = centre + half_width * np.linspace(-1.0, 1.0, REACHABLE_DIRECTIONS)
        return np.stack([np.cos(angles), np.sin(angles)], axis=1)

    def ray_intervals(self, directions, max_speed):
        """Return the allowed ``t`` (speed / ``max_speed``) on each ray: (lower, upper), each (M,).

        An empty interval has ``lower > upper``.
        """
        lower = np.zeros(directions.shape[0])
        upper = np.ones(directions.shape[0])
        if self.accelerating:
            along = directions @ self.current
            discriminant = along * along - self.current @ self.current + self.max_change ** 2
            root = np.sqrt(np.maximum(discriminant, 0.0))
            lower = np.maximum(lower, (along - root) / max_speed)
            upper = np.minimum(upper, np.where(discriminant >= 0.0, along + root, -1.0)
                               / max_speed)
        if self.heading is not None:
            relative = np.arctan2(directions[:, 1], directions[:, 0]) - self.heading
            upper = np.minimum(upper, self.trackable_speed(relative) / max_speed)
        return lower, upper


def relaxed_intervals(limits, directions, max_speed):
    """Each ray's interval; if all are empty, the tracking ones alone (acceleration relaxed).

    A turning robot's trackable set may leave the disc about its last command; it then keeps
    its tracking error bound and lets its command change faster, which the tracking controller
    still limits to what the robot can do.
    """
    lower, upper = limits.ray_intervals(directions, max_speed)
    if np.any(lower <= upper) or limits.heading is None:
        return lower, upper
    return VelocityLimits(heading=limits.heading,
                          trackable_speed=limits.trackable_speed).ray_intervals(
                              directions, max_speed)


def approach_upper(ego, neighbours, directions, config):
    """Return each ray's largest ``t`` under the approach limit, (M,); None where none binds.

    Against each neighbour, the velocity's component along the unit ``n_j`` towards its mean
    position is at most ``rho_j max(gap_j, 0) / T`` (``gap_j`` the mean gap less
    ``safety_margin`` and ``APPROACH_STDS`` stds of the relative position along ``n_j``, ``T``
    the control period; ``rho_j = 1 - a_j`` for a share ``a_j`` in
    (0, 1), else 1/2): on the ray ``t v_max e``, ``t <= rho_j max(gap_j, 0) / (T v_max e.n_j)``
    where ``e.n_j > 0`` (``PlannerConfig.approach_limit``). Two robots that each keep their
    share close the gap by at most all of it within the period, so their disks do not overlap
    within it, whatever course either takes, unless a gap is smaller than both estimate it.

    Parameters
    ----------
    ego : AgentBelief
        The planning robot.
    neighbours : sequence of AgentBelief
        Other robots.
    directions : numpy.ndarray
        Unit ray directions, shape (M, 2).
    config : PlannerConfig
        ``max_speed``, ``control_period``, ``safety_margin``.

    """
    shares = np.array([belief.avoidance_share for belief in neighbours]).reshape(-1)
    # Against a neighbour that announces none or all of the avoidance, half: it may still
    # change course (a robot standing aside moves; a walker turns).
    ego_share = np.where((shares > 0.0) & (shares < 1.0), 1.0 - shares, 0.5)
    towards = np.array([belief.position for belief in neighbours]).reshape(-1, 2) \
        - ego.position
    distance = np.hypot(towards[:, 0], towards[:, 1])
    radii = np.array([belief.radius for belief in neighbours])
    unit = towards / np.maximum(distance, 1e-12)[:, None]
    # The relative position's spread along n_j: each robot's estimate of the gap is noisy,
    # and two robots that each close their share of what they see may close more than all.
    relative = ego.covariance[:2, :2] + np.array(
        [belief.covariance[:2, :2] for belief in neighbours]).reshape(-1, 2, 2)
    spread = np.sqrt(np.maximum(np.einsum('ni,nij,nj->n', unit, relative, unit), 0.0))
    gap = distance - ego.radius - radii - config.safety_margin - APPROACH_STDS * spread
    # The most the ego may close of each gap within a period, as a fraction of max_speed.
    allowance = ego_share * np.maximum(gap, 0.0) / (config.control_period * config.max_speed)
    near = allowance < 1.0
    if not near.any():
        return None
    closing = directions @ unit[near].T
    with np.errstate(divide='ignore'):
        caps = np.where(closing > 0.0, allowance[near] / closing, np.inf)
    return np.minimum(caps.min(axis=1), 1.0)


def free_choice(directions, lower, upper, v_pref, config):
    """Without neighbours: the allowed velocity of the smallest plain cost, (2,)."""
    allowed = lower <= upper
    preferred = directions @ v_pref / config.max_speed
    t = np.clip(preferred, lower, upper)
    candidates = config.max_speed * t[:, None] * directions
    costs = np.where(allowed, np.linalg.norm(candidates - v_pref, axis=1), np.inf)
    return candidates[int(np.argmin(costs))]


def allowed_speed_grid(plan, lower, upper):
    """Return candidate ``t`` (M, T) within each ray's allowed interval and their costs.

    Per ray: the preferred speed (projected) and ``_FALLBACK_FRACTIONS`` of the interval; a ray
    whose interval is empty gets ``t = 0`` at infinite cost.
    """
    allowed = lower <= upper
    span = np.where(allowed, upper - lower, 0.0)
    speeds = np.concatenate([np.clip(plan.preferred, lower, upper)[:, None],
                             lower[:, None] + span[:, None] * _FALLBACK_FRACTIONS], axis=1)
    speeds = np.where(allowed[:, None], speeds, 0.0)
    costs = choice_costs(plan.config.max_speed * speeds[..., None] * plan.directions[:, None, :],
                         plan.v_pref, plan.previous, plan.config)
    return speeds, np.where(allowed[:, None], costs, np.inf)
