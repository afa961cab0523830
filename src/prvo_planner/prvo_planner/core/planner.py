"""
The PRVO velocity planner and its baselines: one call, ``plan_velocity``.

One call builds, for every (neighbour, candidate direction) pair, the mean and variance
polynomials of every condition in the ray parameter ``t`` (speed ``t v_max``), finds each pair's
accepted speeds in closed form, intersects them per direction by a sorted sweep over the
rejected pieces, and picks the feasible velocity with the smallest choice cost. Everything is
vectorised over neighbours and directions. The steps live in ``encounter`` (relative Gaussians,
candidate directions), ``feasibility`` (accepted intervals, achieved margins) and ``choice``
(costs, fallback ranking).
"""

import math

import numpy as np

from .beliefs import AgentBelief, as_finite_array
from .choice import (
    INTERIOR,
    best_ranked,
    best_speeds,
    choice_costs,
    grid_scores,
    speed_grid,
)
from .config import PlannerConfig, PlanResult
from .encounter import build_encounter, candidate_directions, condition_layout, model_moments
from .feasibility import achieved_margins, monte_carlo_probabilities, ray_gaps
from .moments import condition_moments, poly_eval, ray_polynomials
from .probability import eta_from_k


def _validated_inputs(ego, neighbours, v_pref, config, previous):
    if not isinstance(ego, AgentBelief):
        raise ValueError(f'ego must be an AgentBelief, got {ego!r}')
    neighbours = list(neighbours)
    for index, neighbour in enumerate(neighbours):
        if not isinstance(neighbour, AgentBelief):
            raise ValueError(f'neighbours[{index}] must be an AgentBelief, got {neighbour!r}')
    if not isinstance(config, PlannerConfig):
        raise ValueError(f'config must be a PlannerConfig, got {config!r}')
    if previous is not None:
        previous = as_finite_array(previous, (2,), 'previous')
    return neighbours, as_finite_array(v_pref, (2,), 'v_pref'), previous


def _clip_speed(velocity, max_speed):
    speed = math.hypot(velocity[0], velocity[1])
    return velocity * (max_speed / speed) if speed > max_speed else np.array(velocity)


def plan_velocity(ego, neighbours, v_pref, config, previous=None):
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

    Returns
    -------
    PlanResult
        The velocity (never NaN, ``|v| <= max_speed``) and its diagnostics.

    Raises
    ------
    ValueError
        On invalid inputs.

    """
    neighbours, v_pref, previous = _validated_inputs(ego, neighbours, v_pref, config, previous)
    encounter = build_encounter(ego, neighbours, config)
    count = encounter.origin.shape[0]
    directions = candidate_directions(ego, v_pref, config)
    if count == 0:
        return PlanResult(velocity=_clip_speed(v_pref, config.max_speed), feasible=True,
                          achieved_k=math.inf, eta_bound=1.0, num_constraints=0,
                          candidates_feasible=directions.shape[0])
    layout = condition_layout(encounter, config)
    preferred = directions @ v_pref / config.max_speed
    if config.model == 'mc':
        speeds, grid_costs = speed_grid(directions, preferred, v_pref, previous, config)
        probabilities = monte_carlo_probabilities(encounter, layout, directions, speeds,
                                                   config, np.random.default_rng(config.seed))
        feasible_points = np.all(probabilities >= encounter.eta, axis=0)
        candidates_feasible = int(np.count_nonzero(np.any(feasible_points, axis=1)))
        if candidates_feasible:
            flat = int(np.argmin(np.where(feasible_points, grid_costs, np.inf)))
        else:
            flat = best_ranked(np.min(probabilities, axis=0), grid_costs)
        direction_index, speed_index = np.unravel_index(flat, speeds.shape)
        velocity = config.max_speed * speeds[direction_index, speed_index] * \
            directions[direction_index]
    else:
        cov, radius, deterministic = model_moments(encounter, config)
        means, variances = ray_polynomials(encounter.origin, cov, radius, directions,
                                           config.max_speed, config.time_horizon,
                                           layout.has_receding)
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, config.method, deterministic, preferred)
        candidates_feasible = int(np.count_nonzero(
            np.bincount(gap_direction, minlength=directions.shape[0])))
        if candidates_feasible:
            # The best speed on a ray within one interval (the preferred one, projected, under
            # the plain cost).
            inset = np.minimum(INTERIOR, 0.5 * (upper - lower))
            best_t = best_speeds(directions[gap_direction], lower + inset, upper - inset,
                                  preferred[gap_direction], v_pref, previous, config)
            candidates = config.max_speed * best_t[:, None] * directions[gap_direction]
            best = int(np.argmin(choice_costs(candidates, v_pref, previous, config)))
            direction_index, chosen_t = gap_direction[best], best_t[best]
        else:
            speeds, grid_costs = speed_grid(directions, preferred, v_pref, previous, config)
            score = grid_scores(means, variances, speeds, layout, deterministic)
            direction_index, speed_index = np.unravel_index(best_ranked(score, grid_costs),
                                                            speeds.shape)
            chosen_t = speeds[direction_index, speed_index]
        velocity = config.max_speed * chosen_t * directions[direction_index]
    if config.model == 'prvo':
        # The planning moments are the beliefs' own: evaluate the ray polynomials.
        at_velocity = [poly_eval(polynomial[:, direction_index], chosen_t)
                       for polynomial in (means, variances)]
    else:
        at_velocity = [moment[:, 0] for moment in condition_moments(
            encounter.origin, encounter.cov, encounter.combined_radius, velocity[None, :],
            config.time_horizon, layout.has_receding)]
    achieved = float(achieved_margins(*at_velocity, layout, layout.receding_enabled).min())
    velocity = _clip_speed(velocity, config.max_speed)
    return PlanResult(velocity=velocity,
                      feasible=bool(candidates_feasible) and not encounter.overlapping.any(),
                      achieved_k=achieved, eta_bound=eta_from_k(max(achieved, 0.0)),
                      num_constraints=count, candidates_feasible=candidates_feasible)
