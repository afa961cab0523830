"""Planner configuration and result types."""

from dataclasses import dataclass, field
import math
import numbers

import numpy as np

from .beliefs import as_covariance, as_finite_array
from .probability import eta_from_k, k_from_eta

METHODS = ('exact', 'taylor')
MODELS = ('prvo', 'rvo', 'inflate', 'mc')
RISKS = ('pairwise', 'joint')
CERTIFICATES = ('cantelli', 'certified')
BOUND_KINDS = ('cantelli', 'certified')
_KIND_SET = frozenset(BOUND_KINDS)


def _positive(value, field_name, allow_inf=False):
    """Return ``value`` as a float, requiring it to be > 0 (and finite unless allowed)."""
    number = _real(value, field_name, allow_inf)
    if not number > 0.0:
        raise ValueError(f'{field_name} must be > 0, got {value!r}')
    return number


def _real(value, field_name, allow_inf=False):
    """Return ``value`` as a float, rejecting NaN, non-numbers and (unless allowed) inf."""
    # A float needs no abstract-class check: configurations are rebuilt on every plan.
    if type(value) is not float and (isinstance(value, bool)
                                     or not isinstance(value, numbers.Real)):
        raise ValueError(f'{field_name} must be a real number, got {value!r}')
    number = float(value)
    if math.isnan(number) or (math.isinf(number) and not (allow_inf and number > 0)):
        raise ValueError(f'{field_name} must be finite{" or +inf" if allow_inf else ""}, '
                         f'got {value!r}')
    return number


def _integer(value, field_name, minimum):
    """Return ``value`` as an int, requiring it to be >= ``minimum``."""
    integral = type(value) is int or (not isinstance(value, bool)
                                      and isinstance(value, numbers.Integral))
    if not integral or value < minimum:
        raise ValueError(f'{field_name} must be an integer >= {minimum}, got {value!r}')
    return int(value)


def _choice(value, field_name, choices):
    """Return ``value`` if it is one of ``choices``."""
    if value not in choices:
        raise ValueError(f'{field_name} must be one of {choices}, got {value!r}')
    return value


@dataclass(frozen=True)
class PlannerConfig:
    """
    Parameters of :func:`plan_velocity`, validated on construction.

    Attributes
    ----------
    eta : float
        Required probability of satisfying each (pairwise) constraint, in (0, 1).
    k : float or None
        Surrogate margin ``mu - k sigma >= 0``; when given it wins over ``eta``.
    max_speed : float
        Speed limit ``v_max``, m/s, > 0.
    num_directions : int
        Number ``M`` of evenly spaced candidate headings, >= 1.
    time_horizon : float
        ``tau``, seconds, > 0; ``math.inf`` disables the horizon alternative.
    neighbor_distance : float
        Neighbours whose mean surface-to-surface distance exceeds this are ignored, metres.
    actuation_cov : numpy.ndarray
        Actuation noise covariance ``S_a``, shape (2, 2).
    safety_margin : float
        Added to the sum of radii, metres, >= 0.
    method : str
        ``'exact'`` (quartic) or ``'taylor'`` (the paper's quadratic approximation).
    model : str
        ``'prvo'``, ``'rvo'`` (means only), ``'inflate'`` (enlarged radius) or ``'mc'``.
    receding_gate : bool
        Also accept velocities that move apart (``r . u >= 0``) with margin ``k``.
    risk : str
        ``'pairwise'`` (``eta`` per neighbour) or ``'joint'`` (``1 - (1 - eta) / n`` each).
    mc_samples : int
        Samples per neighbour for ``model='mc'``, >= 1.
    seed : int or None
        Seeds the heading offset and the ``mc`` samples; ``None`` means no offset.
    inertia : float
        Weight ``w`` in [0, 1) of ``|v - v_prev|`` in the choice cost
        ``|v - v_pref| + w |v - v_prev| + b max(0, left(v))``, where ``v_prev`` is the
        previous command passed to :func:`plan_velocity` (no term without one). It only ranks
        velocities that meet the constraints: it damps the step-to-step side flips of the
        closest-to-``v_pref`` rule (RVO's reciprocal dance). Below 1, so that in free space the
        robot still speeds up to ``v_pref``.
    passing_bias : float
        ``b >= 0``: cost per m/s of velocity to the left of ``v_pref``'s direction. A common
        convention (pass on the right) that breaks the tie between the two mirror-equal ways
        around a symmetric encounter the same way for every robot.
    progress_weight : float
        Share ``p`` in [0, 1) of the goal term of the choice cost given to the speed lost
        towards the goal: ``(1 - p) |v - v_pref| + p | |v_pref| - along(v) |``, ``along`` the
        component of ``v`` along ``v_pref``. Sideways speed then costs less than slowing down
        behind a crowd. It only ranks velocities that meet the constraints. Below 1, so that
        sideways speed still costs something.
    control_period : float
        How long a command stays in force, seconds, > 0 (the simulator's ``dt`` by default):
        without a feasible velocity, a neighbour the command would touch within it counts as
        in contact; against static obstacles each period's execution error is its own.
    certificate : str
        The bound a velocity must meet ``eta`` with (docs/method.md, section 13):
        ``'cantelli'`` (the margin ``k`` on every condition) or ``'certified'`` (for
        ``model='prvo'``: rays searched with the smaller margin at which the Gaussian bound
        typically reaches ``eta``, the chosen velocity certified against every neighbour, and
        Cantelli's margin restored for the neighbours it falls short for).
    obstacle_horizon : float
        ``tau`` against static obstacles, seconds, > 0, finite (as RVO2's ``timeHorizonObst``):
        a wall is a constraint on the path over the next ``tau`` seconds, the command kept
        and executed with an error of its own every ``control_period``. Longer:
        robots slow down earlier and keep further from walls; shorter: they pass closer and
        may approach a wall faster than they can stop.
    guard_time : float
        Seconds, >= 0: a neighbour that takes a share of the avoidance and could touch the
        robot within this time (its mean gap below ``guard_time`` times ``max_speed`` plus the
        neighbour's speed) is judged twice, as it announces and as if it kept its velocity
        (share 0, the plain velocity obstacle) over ``guard_time``; the velocity must meet
        both. Near contact, safety then does not rest on the reciprocal assumption, which two
        robots that change course at once break (docs/method.md, section 11). 0: off.
    approach_limit : bool
        Near contact, close at most the robot's share of the mean gap to each neighbour in one
        ``control_period``: against a neighbour of share ``a_j`` in (0, 1) the velocity's
        component towards it at most ``(1 - a_j) gap / control_period``, against one that
        announces none or all of the avoidance (it may still change course) half the gap.
        Two robots that both keep it cannot meet within the period whatever either does, also
        when both change course at once, which neither the reciprocal row nor the guard
        holds against (docs/method.md, section 11). It binds only within ``control_period``
        times ``max_speed`` divided by the robot's share (0.2 m at half, 1 m/s and 0.1 s).
    """

    eta: float = 0.8
    k: float | None = None
    max_speed: float = 1.0
    num_directions: int = 64
    time_horizon: float = 5.0
    neighbor_distance: float = 10.0
    actuation_cov: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    safety_margin: float = 0.0
    method: str = 'exact'
    model: str = 'prvo'
    receding_gate: bool = True
    risk: str = 'pairwise'
    mc_samples: int = 1000
    seed: int | None = None
    inertia: float = 0.0
    passing_bias: float = 0.0
    progress_weight: float = 0.0
    control_period: float = 0.1
    certificate: str = 'cantelli'
    obstacle_horizon: float = 2.0
    guard_time: float = 0.0
    approach_limit: bool = False

    def __post_init__(self):
        eta = _real(self.eta, 'PlannerConfig.eta')
        if not 0.0 < eta < 1.0:
            raise ValueError(f'PlannerConfig.eta must be in (0, 1), got {self.eta!r}')
        object.__setattr__(self, 'eta', eta)
        if self.k is not None:
            k = _real(self.k, 'PlannerConfig.k')
            if k < 0.0:
                raise ValueError(f'PlannerConfig.k must be >= 0, got {self.k!r}')
            object.__setattr__(self, 'k', k)
        object.__setattr__(self, 'max_speed', _positive(self.max_speed, 'PlannerConfig.max_speed'))
        object.__setattr__(self, 'num_directions',
                           _integer(self.num_directions, 'PlannerConfig.num_directions', 1))
        object.__setattr__(self, 'time_horizon',
                           _positive(self.time_horizon, 'PlannerConfig.time_horizon', True))
        object.__setattr__(self, 'neighbor_distance',
                           _positive(self.neighbor_distance, 'PlannerConfig.neighbor_distance',
                                     True))
        object.__setattr__(self, 'actuation_cov',
                           as_covariance(self.actuation_cov, 2, 'PlannerConfig.actuation_cov'))
        margin = _real(self.safety_margin, 'PlannerConfig.safety_margin')
        if margin < 0.0:
            raise ValueError(f'PlannerConfig.safety_margin must be >= 0, '
                             f'got {self.safety_margin!r}')
        object.__setattr__(self, 'safety_margin', margin)
        _choice(self.method, 'PlannerConfig.method', METHODS)
        _choice(self.model, 'PlannerConfig.model', MODELS)
        _choice(self.risk, 'PlannerConfig.risk', RISKS)
        _choice(self.certificate, 'PlannerConfig.certificate', CERTIFICATES)
        if not isinstance(self.receding_gate, (bool, np.bool_)):
            raise ValueError(f'PlannerConfig.receding_gate must be a bool, got '
                             f'{self.receding_gate!r}')
        object.__setattr__(self, 'receding_gate', bool(self.receding_gate))
        object.__setattr__(self, 'mc_samples',
                           _integer(self.mc_samples, 'PlannerConfig.mc_samples', 1))
        if self.seed is not None:
            object.__setattr__(self, 'seed', _integer(self.seed, 'PlannerConfig.seed', 0))
        inertia = _real(self.inertia, 'PlannerConfig.inertia')
        if not 0.0 <= inertia < 1.0:
            raise ValueError(f'PlannerConfig.inertia must be in [0, 1), got {self.inertia!r}')
        object.__setattr__(self, 'inertia', inertia)
        bias = _real(self.passing_bias, 'PlannerConfig.passing_bias')
        if bias < 0.0:
            raise ValueError(f'PlannerConfig.passing_bias must be >= 0, '
                             f'got {self.passing_bias!r}')
        object.__setattr__(self, 'passing_bias', bias)
        progress = _real(self.progress_weight, 'PlannerConfig.progress_weight')
        if not 0.0 <= progress < 1.0:
            raise ValueError(f'PlannerConfig.progress_weight must be in [0, 1), '
                             f'got {self.progress_weight!r}')
        object.__setattr__(self, 'progress_weight', progress)
        object.__setattr__(self, 'control_period',
                           _positive(self.control_period, 'PlannerConfig.control_period'))
        object.__setattr__(self, 'obstacle_horizon',
                           _positive(self.obstacle_horizon, 'PlannerConfig.obstacle_horizon'))
        guard = _real(self.guard_time, 'PlannerConfig.guard_time')
        if guard < 0.0:
            raise ValueError(f'PlannerConfig.guard_time must be >= 0, got {self.guard_time!r}')
        object.__setattr__(self, 'guard_time', guard)
        if not isinstance(self.approach_limit, (bool, np.bool_)):
            raise ValueError(f'PlannerConfig.approach_limit must be a bool, '
                             f'got {self.approach_limit!r}')
        object.__setattr__(self, 'approach_limit', bool(self.approach_limit))

    @property
    def effective_k(self):
        """The pairwise surrogate margin in force: ``k`` if given, else ``k_from_eta(eta)``."""
        return self.k if self.k is not None else k_from_eta(self.eta)

    @property
    def effective_eta(self):
        """The pairwise probability in force: ``eta_from_k(k)`` if ``k`` is given, else ``eta``."""
        return eta_from_k(float(self.k)) if self.k is not None else self.eta


@dataclass(frozen=True)
class PlanResult:
    """
    Output of :func:`plan_velocity`.

    Attributes
    ----------
    velocity : numpy.ndarray
        Commanded velocity, shape (2,), never NaN, ``|velocity| <= max_speed``.
    feasible : bool
        Whether the velocity meets every constraint of the configured model.
    achieved_k : float
        Smallest over neighbours of the largest margin ``k`` an accepted condition meets at
        ``velocity`` under the given beliefs (``inf`` when nothing constrains).
    eta_bound : float
        Smallest over neighbours of ``neighbour_bounds``; with ``certificate='cantelli'``
        Cantelli's bound ``k^2 / (1 + k^2)`` of ``max(achieved_k, 0)``.
    num_constraints : int
        Number of neighbours considered.
    candidates_feasible : int
        Number of candidate directions with a feasible speed.
    neighbour_bounds : numpy.ndarray
        Per neighbour considered, a lower bound on the probability that its accepted condition
        holds at ``velocity``, shape (num_constraints,).
    bound_kinds : tuple of str
        Per neighbour, which bound that is: ``'certified'`` (the Gaussian bound of
        docs/method.md, section 13, on ``f`` or ``g``) or ``'cantelli'``.
    certificate : str
        The configuration's ``certificate``.
    obstacle_clearance : float
        Distance of the ego's mean from the nearest static obstacle's surface grown by the
        planning radius and margin [m], negative inside (``inf`` without obstacles).
    obstacle_probability : float
        Smallest over the static obstacles of the probability certified that the path over
        the obstacle horizon avoids it at ``velocity`` (1 without obstacles).

    """

    velocity: np.ndarray
    feasible: bool
    achieved_k: float
    eta_bound: float
    num_constraints: int
    candidates_feasible: int
    neighbour_bounds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bound_kinds: tuple = ()
    certificate: str = 'cantelli'
    obstacle_clearance: float = math.inf
    obstacle_probability: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, 'velocity',
                           as_finite_array(self.velocity, (2,), 'PlanResult.velocity'))
        object.__setattr__(self, 'bound_kinds', tuple(self.bound_kinds))
        if len(self.bound_kinds) != len(self.neighbour_bounds):
            raise ValueError(f'PlanResult.bound_kinds must have one entry per neighbour bound '
                             f'({len(self.neighbour_bounds)}), got {len(self.bound_kinds)}')
        if not _KIND_SET.issuperset(self.bound_kinds):
            for kind in self.bound_kinds:
                _choice(kind, 'PlanResult.bound_kinds', BOUND_KINDS)
        _choice(self.certificate, 'PlanResult.certificate', CERTIFICATES)
