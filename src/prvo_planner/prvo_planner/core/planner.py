"""
The PRVO velocity planner and its baselines: ``plan_velocity``, and ``plan_velocities``.

``plan_velocity`` plans one robot, ``plan_velocities`` a team at once.

One plan builds, for every (neighbour, candidate direction) pair, the mean and variance
polynomials of every condition in the ray parameter ``t`` (speed ``t v_max``), finds each pair's
accepted speeds in closed form, intersects them per direction by a sorted sweep over the
rejected pieces, and picks the feasible velocity with the smallest choice cost. Everything is
vectorised over neighbours and directions, and ``plan_velocities`` stacks the neighbours and
directions of every robot of a team into the same few numpy calls; a robot's values are
computed by the same operations whatever it is planned with, so its plan is bit for bit the
one ``plan_velocity`` returns. The steps live in ``encounter`` (relative Gaussians, candidate
directions), ``feasibility`` (accepted intervals, achieved margins) and ``choice`` (costs,
fallback ranking). With ``certificate='certified'`` the search runs with smaller margins and the
chosen velocity is certified per neighbour (``certificate``; docs/method.md, section 13).
"""

from dataclasses import dataclass, replace
from functools import lru_cache
import math

import numpy as np

from .beliefs import AgentBelief, as_finite_array
from .certificate import (
    condition_bound,
    condition_bound_until_short,
    horizon_search_margin,
    search_margin,
)
from .choice import (
    CostTerms,
    cheapest_velocities,
    fallback_index,
    fallback_measures,
    ranking_radius,
    speed_grid,
)
from .config import PlannerConfig, PlanResult
from .encounter import (
    ConditionLayout,
    Encounter,
    build_encounter,
    candidate_directions,
    condition_layout,
    model_moments,
)
from .feasibility import RayRows, achieved_margins, monte_carlo_probabilities, team_ray_gaps
from .limits import (
    VelocityLimits,
    allowed_speed_grid,
    approach_upper,
    free_choice,
    relaxed_intervals,
)
from .moments import (
    NODES,
    bivariate_polynomials,
    condition_margins,
    condition_moments,
)
from .obstacles import StaticObstacles
from .probability import cantelli_of_margins, eta_from_k
from .walls import (
    WallModel,
    cut_by_walls,
    obstacle_probability,
    rejected_intervals,
    wall_intrusion,
    wall_model,
    wall_time_to_contact,
)

_BELIEF_TYPE = frozenset([AgentBelief])
# Links (neighbour, direction) solved in one call of a team at most (`_batches`): some 6 MB
# of polynomials; from 10,000 to 100,000 the 48-robot circle's step costs the same, and 2,000
# (a robot a call) 6-10% more in the interpreter (docs/results.md, 5.22).
LINK_BATCH = 20000


def _validated_inputs(ego, neighbours, v_pref, config, previous, limits, obstacles=None):
    if obstacles is not None and not isinstance(obstacles, StaticObstacles):
        raise ValueError(f'obstacles must be StaticObstacles or None, got {obstacles!r}')
    if obstacles is not None and len(obstacles) and config.model == 'mc':
        raise ValueError("obstacles are not supported with model='mc'")
    if limits is not None and not isinstance(limits, VelocityLimits):
        raise ValueError(f'limits must be VelocityLimits or None, got {limits!r}')
    if not isinstance(ego, AgentBelief):
        raise ValueError(f'ego must be an AgentBelief, got {ego!r}')
    neighbours = list(neighbours)
    # One C-level pass over the types; the loop only where one is not exactly AgentBelief.
    if not _BELIEF_TYPE.issuperset(map(type, neighbours)):
        for index, neighbour in enumerate(neighbours):
            if not isinstance(neighbour, AgentBelief):
                raise ValueError(f'neighbours[{index}] must be an AgentBelief, '
                                 f'got {neighbour!r}')
    if not isinstance(config, PlannerConfig):
        raise ValueError(f'config must be a PlannerConfig, got {config!r}')
    if previous is not None:
        previous = as_finite_array(previous, (2,), 'previous')
    return neighbours, as_finite_array(v_pref, (2,), 'v_pref'), previous


def _clip_speed(velocity, max_speed):
    speed = math.hypot(velocity[0], velocity[1])
    return velocity * (max_speed / speed) if speed > max_speed else np.array(velocity)


def plan_velocity(ego, neighbours, v_pref, config, previous=None, limits=None, obstacles=None):
    """
    Choose the commanded velocity closest to ``v_pref`` that meets the chance constraints.

    "Closest" is the cost of :func:`choice_costs`: the distance to ``v_pref`` unless
    ``config.inertia`` or ``config.passing_bias`` add their terms.

    Parameters
    ----------
    ego : AgentBelief
        Belief over the planning robot (its mean velocity is a candidate direction).
    neighbours : sequence of AgentBelief
        Beliefs over the other robots.
    v_pref : array_like
        Preferred velocity, shape (2,).
    config : PlannerConfig
        Planner parameters.
    previous : array_like or None
        The previous command, shape (2,), for ``config.inertia``; None for none.
    limits : VelocityLimits or None
        What the robot can command next (acceleration, tracking); None: any velocity.
    obstacles : StaticObstacles or None
        Walls and discs that never move (docs/method.md, walls); None or empty: none.

    Returns
    -------
    PlanResult
        The velocity (never NaN, ``|v| <= max_speed``) and its diagnostics.

    Raises
    ------
    ValueError
        On invalid inputs.

    """
    return plan_velocities([ego], [neighbours], [v_pref], [config], [previous], [limits],
                           [obstacles])[0]


def plan_velocities(egos, neighbours_per_ego, v_prefs, configs, previous=None, limits=None,
                    obstacles=None):
    """
    Plan every robot of a team in few, large numpy calls.

    Result ``i`` is bit for bit ``plan_velocity(egos[i], neighbours_per_ego[i], v_prefs[i],
    configs[i], previous[i])``. Robots whose plans share their structure (model, method,
    conditions) are solved together, whatever their time horizons and numbers of neighbours and
    directions, as in a team of one configuration; ``model='mc'`` plans one robot at a time.

    Parameters
    ----------
    egos : sequence of AgentBelief
        The planning robots.
    neighbours_per_ego : sequence of sequences of AgentBelief
        Each robot's neighbours.
    v_prefs : sequence of array_like
        Each robot's preferred velocity, shape (2,).
    configs : PlannerConfig or sequence of PlannerConfig
        One configuration for every robot, or one per robot.
    previous : None or sequence of (array_like or None)
        Each robot's previous command; None: none for any robot.
    limits : None or sequence of (VelocityLimits or None)
        Each robot's limits; None: none for any robot.
    obstacles : None or sequence of (StaticObstacles or None)
        Each robot's static obstacles; None: none for any robot.

    Returns
    -------
    list of PlanResult
        One per robot, in order.

    Raises
    ------
    ValueError
        On invalid inputs, naming the robot.

    """
    egos = list(egos)
    count = len(egos)
    if isinstance(configs, PlannerConfig):
        configs = [configs] * count
    per_robot = {'neighbours_per_ego': list(neighbours_per_ego), 'v_prefs': list(v_prefs),
                 'configs': list(configs),
                 'previous': [None] * count if previous is None else list(previous),
                 'limits': [None] * count if limits is None else list(limits),
                 'obstacles': [None] * count if obstacles is None else list(obstacles)}
    for name, values in per_robot.items():
        if len(values) != count:
            raise ValueError(f'{name} must have one entry per ego ({count}), got {len(values)}')
    results = [None] * count
    groups = {}
    for index in range(count):
        try:
            plan = _prepared_plan(egos[index], per_robot['neighbours_per_ego'][index],
                                  per_robot['v_prefs'][index], per_robot['configs'][index],
                                  per_robot['previous'][index], per_robot['limits'][index],
                                  per_robot['obstacles'][index])
        except ValueError as error:
            raise ValueError(f'robot {index}: {error}') from error
        if plan.encounter.origin.shape[0] == 0 and plan.walls is not None:
            results[index] = _wall_only_plan(plan)
        elif plan.encounter.origin.shape[0] == 0:
            velocity = (_clip_speed(plan.v_pref, plan.config.max_speed) if plan.allowed is None
                        else free_choice(plan.directions, *plan.allowed, plan.v_pref,
                                         plan.config))
            results[index] = PlanResult(
                velocity=velocity, feasible=True,
                achieved_k=math.inf, eta_bound=1.0, num_constraints=0,
                candidates_feasible=plan.directions.shape[0],
                certificate=plan.config.certificate)
        elif plan.config.model == 'mc':
            results[index] = _monte_carlo_plan(plan)
        else:
            groups.setdefault(plan.structure, []).append((index, plan))
    for members in groups.values():
        for batch in _batches(members):
            for index, result in zip([index for index, _ in batch],
                                     _solve_group([plan for _, plan in batch]), strict=True):
                results[index] = result
    return results


def _batches(members):
    """Split MEMBERS, (index, plan) pairs of one structure, into runs of at most LINK_BATCH links.

    A plan's (neighbour, direction) links are solved alone, so a batch changes no plan; it
    bounds the arrays of one call (about 64 bytes of polynomials a link and condition), which for
    a whole crowd reach hundreds of megabytes, mapped afresh and streamed through memory by every
    stage (docs/results.md, 5.22). A plan with more links than that is a batch of its own.
    """
    batch, links = [], 0
    for member in members:
        plan = member[1]
        size = plan.encounter.origin.shape[0] * plan.directions.shape[0]
        if batch and links + size > LINK_BATCH:
            yield batch
            batch, links = [], 0
        batch.append(member)
        links += size
    if batch:
        yield batch


@dataclass(frozen=True)
class _Plan:
    """One robot's validated inputs and the quantities derived from them alone."""

    v_pref: np.ndarray
    config: PlannerConfig
    previous: np.ndarray | None
    encounter: Encounter
    directions: np.ndarray
    preferred: np.ndarray
    layout: ConditionLayout
    cov: np.ndarray
    radius: np.ndarray
    deterministic: bool
    # Allowed t on each direction (lower, upper), (M,) each; None: [0, 1] everywhere.
    allowed: tuple | None = None
    # Static obstacles (None: none), and the open intervals (upper, lower) of t they reject on
    # each direction, (K, M) each.
    walls: WallModel | None = None
    wall_rejected: tuple | None = None

    @property
    def structure(self):
        """What plans solved together must share: the kind of problem, not its size or horizon."""
        return (self.config.model, self.config.method, self.layout.has_horizon,
                self.layout.has_receding, self.deterministic, self.config.certificate)


def _prepared_plan(ego, neighbours, v_pref, config, previous, limits=None, obstacles=None):
    neighbours, v_pref, previous = _validated_inputs(ego, neighbours, v_pref, config, previous,
                                                     limits, obstacles)
    encounter = build_encounter(ego, neighbours, config)
    directions = candidate_directions(ego, v_pref, config)
    allowed = None
    if limits is not None:
        directions = np.concatenate([directions, limits.extra_directions()])
        allowed = relaxed_intervals(limits, directions, config.max_speed)
    if config.approach_limit and neighbours:
        allowed = _approach_limited(allowed, approach_upper(ego, neighbours, directions, config))
    layout = condition_layout(encounter, config) if encounter.origin.shape[0] else None
    cov, radius, deterministic = (model_moments(encounter, config)
                                  if layout is not None and config.model != 'mc'
                                  else (None, None, False))
    walls = wall_model(obstacles, ego, config) if obstacles is not None and len(obstacles) \
        else None
    return _Plan(v_pref=v_pref, config=config, previous=previous, encounter=encounter,
                 directions=directions, preferred=directions @ v_pref / config.max_speed,
                 layout=layout, cov=cov, radius=radius, deterministic=deterministic,
                 allowed=allowed, walls=walls,
                 wall_rejected=None if walls is None else rejected_intervals(walls, directions))


def _approach_limited(allowed, upper):
    """Return ALLOWED ((lower, upper) or None) cut to the approach limit's UPPER (or None).

    What the robot can do comes first: where the cut would leave no ray an interval, the
    limits stand alone.
    """
    if upper is None:
        return allowed
    if allowed is None:
        return np.zeros(upper.shape[0]), upper
    lower, cut = allowed[0], np.minimum(allowed[1], upper)
    return (lower, cut) if np.any(lower <= cut) else allowed


def _monte_carlo_plan(plan):
    """Plan by the sampling baseline: probabilities estimated at a grid of candidate speeds."""
    encounter, config, directions = plan.encounter, plan.config, plan.directions
    if plan.allowed is None:
        speeds, grid_costs = speed_grid(directions, plan.preferred, plan.v_pref, plan.previous,
                                        config)
    else:
        # Only allowed speeds are sampled; a ray with none gets an infinite cost.
        speeds, grid_costs = allowed_speed_grid(plan, *plan.allowed)
    probabilities = monte_carlo_probabilities(encounter, plan.layout, directions, speeds,
                                               config, np.random.default_rng(config.seed))
    feasible_points = np.all(probabilities >= encounter.eta, axis=0) & np.isfinite(grid_costs)
    candidates_feasible = int(np.count_nonzero(np.any(feasible_points, axis=1)))
    if candidates_feasible:
        direction_index, speed_index = np.unravel_index(
            int(np.argmin(np.where(feasible_points, grid_costs, np.inf))), speeds.shape)
    else:
        direction_index, speed_index = _fallback_choice(plan, speeds, grid_costs)
    velocity = config.max_speed * speeds[direction_index, speed_index] * \
        directions[direction_index]
    at_velocity = [moment[:, 0] for moment in condition_moments(
        encounter.origin, encounter.cov, encounter.combined_radius, velocity[None, :],
        config.time_horizon, plan.layout.has_receding, encounter.lead)]
    achieved = achieved_margins(*at_velocity, plan.layout, plan.layout.receding_enabled)
    return _result(plan, velocity, candidates_feasible, achieved, cantelli_of_margins(achieved),
                   np.zeros(achieved.shape, dtype=bool))


def _result(plan, velocity, candidates_feasible, achieved, bounds, certified):
    """PLAN's result; ACHIEVED, BOUNDS, CERTIFIED per neighbour (see ``_Choice``)."""
    smallest = float(achieved.min(initial=math.inf))
    config = plan.config
    certificate = config.certificate
    velocity = _clip_speed(velocity, config.max_speed)
    walls = plan.walls
    obstacles = ({} if walls is None else {
        'obstacle_clearance': walls.clearance,
        'obstacle_probability': obstacle_probability(walls, velocity)})
    return PlanResult(velocity=velocity,
                      feasible=bool(candidates_feasible)
                      and not plan.encounter.overlapping.any()
                      and (walls is None or walls.clearance > 0.0),
                      achieved_k=smallest,
                      eta_bound=(eta_from_k(max(smallest, 0.0)) if certificate == 'cantelli'
                                 else float(bounds.min(initial=1.0))),
                      num_constraints=plan.encounter.origin.shape[0],
                      candidates_feasible=candidates_feasible, neighbour_bounds=bounds,
                      bound_kinds=tuple(map(_KINDS.__getitem__, certified.tolist())),
                      certificate=certificate, **obstacles)


# A neighbour's bound kind by whether it is certified.
_KINDS = ('cantelli', 'certified')


def _wall_only_plan(plan):
    """Plan a robot whose only constraints are static obstacles (else the fallback)."""
    rays = plan.directions.shape[0]
    lower, upper = (np.zeros(rays), np.ones(rays)) if plan.allowed is None else plan.allowed
    reachable = lower <= upper
    gap_ray, lower, upper = cut_by_walls(np.flatnonzero(reachable), lower[reachable],
                                         upper[reachable], 0, plan.wall_rejected)
    candidates_feasible = int(np.unique(gap_ray).size)
    if candidates_feasible:
        rows = RayRows(means=np.zeros((0, 1, 3)), variances=np.zeros((0, 1, 5)),
                       margins=np.zeros((0, 1)), link_ray=np.zeros(0, dtype=int),
                       link_enabled=np.zeros(0, dtype=bool), ray_local=np.arange(rays),
                       ray_robot=np.zeros(rays, dtype=int), preferred=plan.preferred)
        _, direction, chosen_t = cheapest_velocities(
            gap_ray, lower, upper, plan.directions, rows,
            CostTerms.of_plan(plan.v_pref, plan.previous, plan.config),
            np.array([plan.config.max_speed]))
        direction_index, t = int(direction[0]), chosen_t[0]
    else:
        speeds, costs = (speed_grid(plan.directions, plan.preferred, plan.v_pref, plan.previous,
                                    plan.config) if plan.allowed is None
                         else allowed_speed_grid(plan, *plan.allowed))
        direction_index, speed_index = _fallback_choice(plan, speeds, costs)
        t = speeds[direction_index, speed_index]
    empty = np.zeros(0)
    return _result(plan, plan.config.max_speed * t * plan.directions[direction_index],
                   candidates_feasible, empty, empty, np.zeros(0, dtype=bool))


def _wall_gaps(search, gap_ray, lower, upper):
    """Cut the feasible intervals (sorted by ray) of every robot with walls by its walls."""
    plans = search.plans
    if len(plans) == 1:
        if plans[0].walls is None:
            return gap_ray, lower, upper
        return cut_by_walls(gap_ray, lower, upper, 0, plans[0].wall_rejected)
    if all(plan.walls is None for plan in plans):
        return gap_ray, lower, upper
    # Each robot's intervals are a run of the sorted rays.
    bounds = np.searchsorted(gap_ray, np.append(search.ray_starts, search.directions.shape[0]))
    pieces = []
    for robot, plan in enumerate(plans):
        own = slice(bounds[robot], bounds[robot + 1])
        pieces.append((gap_ray[own], lower[own], upper[own]) if plan.walls is None
                      else cut_by_walls(gap_ray[own], lower[own], upper[own],
                                        int(search.ray_starts[robot]), plan.wall_rejected))
    return tuple(np.concatenate(values) for values in zip(*pieces, strict=True))


def _pair_horizons(plans, pair_counts):
    """Return the plans' common time horizon, or each neighbour's plan's, shape (N,)."""
    horizons = [plan.config.time_horizon for plan in plans]
    if all(horizon == horizons[0] for horizon in horizons):
        return horizons[0]
    return np.repeat(horizons, pair_counts)


@dataclass(frozen=True)
class _Search:
    """The rays of robots of one structure, their links, and how neighbours are laid out."""

    plans: list
    rows: RayRows
    # Polynomials (L, P, C) of every link, coefficient-major.
    means: np.ndarray
    variances: np.ndarray
    directions: np.ndarray
    pair_counts: np.ndarray
    pair_starts: np.ndarray
    ray_starts: np.ndarray
    ray_counts: np.ndarray
    link_starts: np.ndarray
    # Neighbour (pair) of every link, and robot of every pair.
    link_pair: np.ndarray
    pair_robot: np.ndarray
    pair_horizons: float | np.ndarray
    # Each robot's choice cost (one row per robot) and v_max, (R,).
    terms: CostTerms
    max_speed: np.ndarray


@dataclass(frozen=True)
class _Choice:
    """Each robot's chosen velocity, and per neighbour the margin and the bound it meets."""

    velocities: np.ndarray
    candidates_feasible: np.ndarray
    achieved: np.ndarray
    bounds: np.ndarray
    certified: np.ndarray


def _certifies(plan):
    """Whether PLAN's velocities are certified: Gaussian beliefs with some uncertainty."""
    return (plan.config.certificate == 'certified' and plan.config.model == 'prvo'
            and not plan.deterministic)


def _solve_group(plans):
    """
    Plan robots of one structure together; return their results in order.

    Robots may differ in their numbers of neighbours and directions: their (neighbour,
    direction) links are laid end to end.
    """
    search = _ray_search(plans)
    choice = (_certified_choice(search) if _certifies(plans[0])
              else _choose(search, search.rows.margins))
    if len(plans) == 1:
        return [_result(plans[0], choice.velocities[0], int(choice.candidates_feasible[0]),
                        choice.achieved, choice.bounds, choice.certified)]
    starts, ends = search.pair_starts.tolist(), (search.pair_starts + search.pair_counts).tolist()
    feasible = choice.candidates_feasible.tolist()
    return [_result(plan, choice.velocities[robot], feasible[robot],
                    *(values[starts[robot]:ends[robot]]
                      for values in (choice.achieved, choice.bounds, choice.certified)))
            for robot, plan in enumerate(plans)]


def _joined(arrays):
    """Concatenate ARRAYS along their first axis; one array is returned as it is."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def _ray_search(plans):
    """
    Build the ray polynomials and links of PLANS (one structure).

    The bivariate fit is one call for every neighbour; the restriction to rays and the links'
    layout one compiled call (:func:`.ray_search.ray_links`).
    """
    from .ray_search import ray_links

    layout = plans[0].layout
    pair_counts = np.array([plan.encounter.origin.shape[0] for plan in plans])
    ray_counts = np.array([plan.directions.shape[0] for plan in plans])
    pair_horizons = _pair_horizons(plans, pair_counts)
    nodes = (plans[0].config.max_speed * NODES if len(plans) == 1 else np.repeat(
        np.stack([plan.config.max_speed * NODES for plan in plans]), pair_counts, axis=0))
    mean_fit, variance_fit = bivariate_polynomials(
        _joined([plan.encounter.origin for plan in plans]),
        _joined([plan.cov for plan in plans]), _joined([plan.radius for plan in plans]), nodes,
        pair_horizons, layout.has_receding, _joined([plan.encounter.lead for plan in plans]))
    directions = _joined([plan.directions for plan in plans])
    (means, variances, margins, link_ray, link_pair, link_enabled, (pair_starts, ray_starts,
     link_starts), ray_local, ray_robot, pair_robot) = ray_links(
        mean_fit.swapaxes(1, 2), variance_fit.swapaxes(1, 2), directions, pair_counts,
        ray_counts, np.array([plan.layout.margins(plan.encounter) for plan in plans]),
        _joined([plan.layout.receding_enabled for plan in plans]))
    rows = RayRows(
        means=means.transpose(1, 2, 0), variances=variances.transpose(1, 2, 0),
        margins=margins, link_ray=link_ray, link_enabled=link_enabled, ray_local=ray_local,
        ray_robot=ray_robot, preferred=_joined([plan.preferred for plan in plans]))
    terms = [CostTerms.of_plan(plan.v_pref, plan.previous, plan.config) for plan in plans]
    return _Search(plans=plans, rows=rows, means=means, variances=variances,
                   directions=directions, pair_counts=pair_counts, pair_starts=pair_starts,
                   ray_starts=ray_starts, ray_counts=ray_counts, link_starts=link_starts,
                   link_pair=link_pair, pair_robot=pair_robot, pair_horizons=pair_horizons,
                   terms=terms[0] if len(terms) == 1 else CostTerms.stacked(
                       terms, np.arange(len(terms))),
                   max_speed=np.array([plan.config.max_speed for plan in plans]))


def _choose(search, margins, robots=None):
    """
    Choose every robot's velocity with MARGINS (P, C) per link; Cantelli's bounds per pair.

    With ROBOTS (B,) only the robots marked are searched: the others' values are not choices.
    """
    plans, directions, ray_starts = search.plans, search.directions, search.ray_starts
    first = plans[0]
    rows = search.rows
    # RayRows built directly: dataclasses.replace costs twice as much, up to three times a plan.
    rows = RayRows(means=rows.means, variances=rows.variances, margins=margins,
                   link_ray=rows.link_ray, link_enabled=rows.link_enabled,
                   ray_local=rows.ray_local, ray_robot=rows.ray_robot, preferred=rows.preferred)
    gap_ray, lower, upper = _wall_gaps(search, *_allowed_gaps(
        plans, *team_ray_gaps(rows, first.layout, first.config.method, first.deterministic,
                              robots)))
    candidates_feasible, direction_index, chosen_t = cheapest_velocities(
        gap_ray, lower, upper, directions, rows, search.terms, search.max_speed)
    searched = np.ones(len(plans), dtype=bool) if robots is None else robots
    for robot in np.flatnonzero((candidates_feasible == 0) & searched):
        plan = plans[robot]
        # Under limits only reachable (and trackable) speeds are candidates.
        speeds, costs = (speed_grid(plan.directions, plan.preferred, plan.v_pref, plan.previous,
                                    plan.config) if plan.allowed is None
                         else allowed_speed_grid(plan, *plan.allowed))
        direction_index[robot], speed_index = _fallback_choice(plan, speeds, costs)
        chosen_t[robot] = speeds[direction_index[robot], speed_index]
    velocities = (search.max_speed * chosen_t)[:, None] * directions[ray_starts
                                                                     + direction_index]
    # Per neighbour of every robot: its link on the robot's chosen direction.
    pair_robot, ray_counts = search.pair_robot, search.ray_counts
    chosen_links = (search.link_starts[pair_robot] + direction_index[pair_robot]
                    + (np.arange(pair_robot.size) - search.pair_starts[pair_robot])
                    * ray_counts[pair_robot])
    achieved = _achieved(plans, search.means, search.variances, chosen_links, pair_robot,
                         chosen_t, velocities, search.pair_horizons)
    return _Choice(velocities=velocities, candidates_feasible=candidates_feasible,
                   achieved=achieved, bounds=cantelli_of_margins(achieved),
                   certified=np.zeros(achieved.shape, dtype=bool))


def _pairs(search, robot):
    """Return the slice of ROBOT's neighbours among the pairs of SEARCH."""
    return slice(search.pair_starts[robot], search.pair_starts[robot] + search.pair_counts[robot])


def _certified_bounds(search, velocities, achieved, required):
    """
    Per neighbour, lower bounds on the probability of its accepted condition, and their kinds.

    VELOCITIES holds per robot None or the velocities (V, 2) to certify, ACHIEVED their margins
    (V, n) against its n neighbours. Cantelli's bound of the achieved margin is the floor. Where
    it falls short of the REQUIRED probability (per pair), the certified bound of the condition
    (:func:`.certificate.condition_bound`: ``P(f >= 0)``, where that too falls short and the
    gate counts ``P(g >= 0)``, then with a finite horizon the whole condition): a neighbour
    Cantelli already certifies costs nothing (most of a crowd's are far). The larger of the two
    bounds is kept; it is certified where it is the Gaussian one. A robot's short entries are
    certified in one call (the floors and the short entries compiled:
    :func:`.certificate_kernels.short_entries`); each entry's bound is its own, so a robot's
    plan does not depend on its companions.

    Returns
    -------
    list
        Per robot None (not certified) or the bounds (V, n) and whether each is certified.

    """
    from .certificate_kernels import short_entries

    results = [None] * len(search.plans)
    for robot, plan in enumerate(search.plans):
        if velocities[robot] is None:
            continue
        encounter = plan.encounter
        # Compiled: the floors, and the short entries' arguments of the certificate.
        floors, short, *entries = short_entries(
            encounter.origin, encounter.lead, plan.cov, plan.radius, velocities[robot],
            achieved[robot], required[_pairs(search, robot)], plan.layout.receding_enabled)
        certified = np.zeros(floors.shape, dtype=bool)
        if short.size:
            gaussian = condition_bound(*entries, plan.config.time_horizon
                                       if plan.layout.has_horizon else None)
            flat = floors.reshape(-1)
            floor = flat[short]
            certified.reshape(-1)[short] = gaussian > floor
            flat[short] = np.maximum(gaussian, floor)
        results[robot] = (floors, certified)
    return results


@dataclass(frozen=True)
class _Anchors:
    """
    A robot's anchors, the preferred velocity and the previous command within ``max_speed``.

    Attributes
    ----------
    terms : CostTerms
        The robot's choice cost.
    velocities : numpy.ndarray
        Shape (A, 2), A in 0-2 (none for a robot with limits or static obstacles).
    costs : numpy.ndarray
        Their choice costs, (A,).
    achieved : numpy.ndarray
        The margins they meet per neighbour, (A, n).

    """

    terms: CostTerms
    velocities: np.ndarray
    costs: np.ndarray
    achieved: np.ndarray

    def eligible(self, velocity, feasible):
        """Return the anchors cheaper than VELOCITY (all if not FEASIBLE), cheapest first."""
        indices = np.arange(self.costs.size)
        if feasible and indices.size:
            indices = indices[self.costs < self.terms.costs(velocity)]
        return indices[np.argsort(self.costs[indices], kind='stable')]


def _anchors(search):
    """Per robot its :class:`_Anchors`."""
    anchors = []
    terms = search.terms
    for robot, plan in enumerate(search.plans):
        config, encounter, layout = plan.config, plan.encounter, plan.layout
        # The robot's choice cost, as the search built it.
        own_terms = terms if len(search.plans) == 1 else CostTerms(
            table=terms.table[robot:robot + 1], extra=terms.extra[robot:robot + 1])
        velocities = np.zeros((0, 2))
        if plan.allowed is None and plan.walls is None:
            velocities = np.array([_clip_speed(anchor, config.max_speed) for anchor in (
                plan.v_pref, plan.previous) if anchor is not None])
        shape = (velocities.shape[0], encounter.origin.shape[0])
        achieved = np.zeros(shape)
        if shape[0]:
            # Every anchor against every neighbour in one compiled call.
            achieved = condition_margins(encounter.origin, plan.cov, plan.radius, velocities,
                                         config.time_horizon, layout.has_receding,
                                         encounter.lead, layout.receding_enabled)
            costs = own_terms.costs(velocities)
        else:
            costs = np.zeros(0)
        anchors.append(_Anchors(terms=own_terms, velocities=velocities, costs=costs,
                                achieved=achieved))
    return anchors


def _certify(search, choice, required, robots):
    """CHOICE with the bounds of the ROBOTS marked certified (:func:`_certified_bounds`)."""
    count = len(search.plans)
    velocities, achieved = [None] * count, [None] * count
    for robot in np.flatnonzero(robots):
        velocities[robot] = choice.velocities[robot][None]
        achieved[robot] = choice.achieved[_pairs(search, robot)][None]
    results = _certified_bounds(search, velocities, achieved, required)
    bounds, certified = choice.bounds.copy(), choice.certified.copy()
    for robot in np.flatnonzero(robots):
        robot_bounds, robot_certified = results[robot]
        pairs = _pairs(search, robot)
        bounds[pairs], certified[pairs] = robot_bounds[0], robot_certified[0]
    return replace(choice, bounds=bounds, certified=certified)


@lru_cache(maxsize=64)
def _search_margins(eta):
    """Return the search margins of the f and g conditions and of the horizon pair for ETA."""
    return float(search_margin(eta)), float(horizon_search_margin(eta))


def _certified_choice(search):
    """
    Choose velocities that meet each neighbour's probability by a stated bound (section 13).

    The f and g conditions are searched with :func:`search_margin` of each neighbour's
    required probability, the horizon pair and the reach condition (where the gate counts, so
    that the horizon certificate applies) with :func:`horizon_search_margin`, and the choice
    certified; then the anchors that may replace it (:func:`_anchored`).
    A robot whose choice falls short for some neighbours searches again with Cantelli's margins
    on those neighbours' links; after a second shortfall, with Cantelli's margins everywhere.
    A robot without a feasible velocity keeps its fallback: larger margins accept no more.
    """
    from .choice_kernels import search_margins

    plans, pair_robot, link_pair = search.plans, search.pair_robot, search.link_pair
    cantelli = search.rows.margins
    etas = [plan.encounter.eta for plan in plans]
    required = np.array(etas)[pair_robot]
    layout = plans[0].layout
    # The reach condition h3 implies the horizon certificate's event, which certifies it.
    margins = search_margins(cantelli, link_pair, pair_robot,
                             np.array([_search_margins(eta) for eta in etas]),
                             _joined([plan.layout.receding_enabled for plan in plans]),
                             1 + layout.has_receding, layout.has_horizon)
    choice = _certify(search, _choose(search, margins), required,
                      np.ones(len(plans), dtype=bool))
    retry = (choice.candidates_feasible > 0) & _any_per_robot(search, choice.bounds < required)
    if retry.any():
        short = (choice.bounds < required) & retry[pair_robot]
        margins = np.where(short[link_pair, None], cantelli, margins)
        choice = _merged(choice, _certify(search, _choose(search, margins, retry), required,
                                          retry), retry, retry[pair_robot])
        retry &= ((choice.candidates_feasible == 0)
                  | _any_per_robot(search, choice.bounds < required))
        if retry.any():
            choice = _merged(choice, _certify(search, _choose(search, cantelli, retry),
                                              required, retry), retry, retry[pair_robot])
    return _anchored(search, choice, required, _anchors(search))


def _anchored(search, choice, required, anchors):
    """
    CHOICE with each robot's anchors (ANCHORS, :class:`_Anchors`) where certified and cheaper.

    The anchors of a robot are its preferred velocity and its previous command (within
    ``max_speed``): the two points the choice cost pulls towards. The search sees each condition
    alone, through its margin, and misses velocities that only the union certifies: slow
    relative motion (a robot at its goal beside a standing neighbour) has a broad direction, so
    neither ``f`` nor ``g`` nor ``h1`` holds with the required probability while the horizon
    bound certifies that nothing is touched within ``tau``. Without the anchors such a robot
    cannot stand still: the velocities it may take lie outside a disc about half its current
    velocity (the reciprocal relative velocity ``2 v - v_i - v_j``), the cheapest of them lies
    opposite, and its commands flip sign every plan for any inertia below 1. An anchor is taken
    only if certified for every neighbour (:func:`_anchor_bounds`, Cantelli's bound the floor)
    and cheaper than the search's choice (any certified anchor, if the search found nothing):
    the cheapest such, tried cheapest first, each until a neighbour falls short. Robots with
    limits or static obstacles keep the search's choice: their anchors are not checked against
    them.
    """
    plans = search.plans
    velocities, candidates_feasible = choice.velocities.copy(), choice.candidates_feasible.copy()
    achieved, bounds, certified = (choice.achieved.copy(), choice.bounds.copy(),
                                   choice.certified.copy())
    for robot in range(len(plans)):
        own = anchors[robot]
        if not own.costs.size:
            continue
        pairs = _pairs(search, robot)
        for index in own.eligible(velocities[robot], candidates_feasible[robot]):
            anchor_bounds = _anchor_bounds(search, robot, own.velocities[index],
                                           own.achieved[index], required[pairs])
            if anchor_bounds is not None:
                velocities[robot] = own.velocities[index]
                candidates_feasible[robot] = max(candidates_feasible[robot], 1)
                achieved[pairs] = own.achieved[index]
                bounds[pairs], certified[pairs] = anchor_bounds
                break
    return _Choice(velocities=velocities, candidates_feasible=candidates_feasible,
                   achieved=achieved, bounds=bounds, certified=certified)


def _anchor_bounds(search, robot, velocity, achieved, required):
    """
    Return an anchor's bounds per neighbour and their kinds if certified against every one.

    VELOCITY (2,) of ROBOT meets the margins ACHIEVED (n,) against its neighbours, which
    REQUIRED (n,) each probability. The bounds are :func:`_certified_bounds`' (Cantelli's
    floor, the certified bound where that falls short), but computed only until a neighbour
    falls short, those likeliest short first (the lowest floors): an anchor short against one
    neighbour is not taken, and a crowd's anchors mostly are not. Returns (bounds (n,),
    certified (n,)), or None for an anchor that is not certified.
    """
    from .certificate_kernels import short_entries

    plan = search.plans[robot]
    encounter = plan.encounter
    floors, short, *entries = short_entries(
        encounter.origin, encounter.lead, plan.cov, plan.radius, velocity[None],
        achieved[None], required, plan.layout.receding_enabled)
    floors = floors[0]
    certified = np.zeros(floors.shape, dtype=bool)
    if short.size:
        order = np.argsort(floors[short], kind='stable')
        gaussian, done = condition_bound_until_short(
            *(entry[order] for entry in entries),
            plan.config.time_horizon if plan.layout.has_horizon else None)
        if done < short.size or gaussian[done - 1] < required[short[order[done - 1]]]:
            return None
        short = short[order]
        certified[short] = gaussian > floors[short]
        floors[short] = np.maximum(gaussian, floors[short])
    return floors, certified


def _any_per_robot(search, flags):
    """Per robot, whether any of its neighbours' FLAGS is set."""
    return np.logical_or.reduceat(flags, search.pair_starts)


def _merged(kept, other, robots, pairs):
    """KEPT with the values of OTHER for the ROBOTS and PAIRS marked."""
    return _Choice(velocities=np.where(robots[:, None], other.velocities, kept.velocities),
                   candidates_feasible=np.where(robots, other.candidates_feasible,
                                                kept.candidates_feasible),
                   **{name: np.where(pairs, getattr(other, name), getattr(kept, name))
                      for name in ('achieved', 'bounds', 'certified')})


def _allowed_gaps(plans, gap_ray, lower, upper):
    """Return the feasible intervals cut to their rays' allowed speeds, empty ones dropped."""
    if all(plan.allowed is None for plan in plans):
        return gap_ray, lower, upper
    allowed_lower, allowed_upper = (np.concatenate([
        np.full(plan.directions.shape[0], fill) if plan.allowed is None else plan.allowed[end]
        for plan in plans]) for end, fill in ((0, 0.0), (1, 1.0)))
    lower = np.maximum(lower, allowed_lower[gap_ray])
    upper = np.minimum(upper, allowed_upper[gap_ray])
    kept = lower <= upper
    return gap_ray[kept], lower[kept], upper[kept]


def _fallback_choice(plan, speeds, costs):
    """
    No feasible velocity: (direction index, speed index) of the fallback among SPEEDS.

    SPEEDS (M, T) are ``t`` per candidate direction, COSTS (M, T) their choice costs; the
    ranking is :func:`fallback_index` of the means against :func:`ranking_radius`.
    """
    config = plan.config
    velocities = config.max_speed * speeds[..., None] * plan.directions[:, None, :]
    encounter = plan.encounter
    intrusion, closing, time_to_collision, left_passes = fallback_measures(
        velocities.reshape(-1, 2), encounter.origin, encounter.lead,
        ranking_radius(encounter, config.model), config.time_horizon, config.control_period)
    # A candidate of infinite cost is out of reach (acceleration, tracking): never chosen.
    reachable = np.isfinite(costs.reshape(-1))
    intrusion = np.where(reachable, intrusion, np.inf)
    walls = (None if plan.walls is None else (
        np.where(reachable, wall_intrusion(plan.walls, velocities.reshape(-1, 2),
                                           config.control_period), np.inf),
        wall_time_to_contact(plan.walls, velocities.reshape(-1, 2))))
    return np.unravel_index(fallback_index(intrusion, closing, time_to_collision, left_passes,
                                           costs.reshape(-1), walls), speeds.shape)


def _achieved(plans, means, variances, chosen_links, pair_robot, chosen_t, velocities,
              pair_horizons):
    """Per neighbour of every robot, the k met at its robot's chosen velocity.

    CHOSEN_LINKS are the links of each neighbour on its robot's chosen direction, robot after
    robot; PAIR_ROBOT the robot of each, PAIR_HORIZONS the time horizon of each (as
    ``_pair_horizons`` gives them).
    """
    first = plans[0]
    enabled = _joined([plan.layout.receding_enabled for plan in plans])
    if first.config.model == 'prvo':
        from .ray_search import link_margins

        # The planning moments are the beliefs' own: evaluate the ray polynomials (compiled).
        return link_margins(means, variances, chosen_links, chosen_t[pair_robot], enabled,
                            first.layout.has_receding, first.layout.has_horizon)
    at_velocity = [moment[:, 0] for moment in condition_moments(
        np.concatenate([plan.encounter.origin for plan in plans]),
        np.concatenate([plan.encounter.cov for plan in plans]),
        np.concatenate([plan.encounter.combined_radius for plan in plans]),
        velocities[pair_robot][:, None, :], pair_horizons,
        first.layout.has_receding,
        np.concatenate([plan.encounter.lead for plan in plans]))]
    return achieved_margins(*at_velocity, first.layout, enabled)
