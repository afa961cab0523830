"""
Standing still on the means alone: the deterministic RVO conditions at zero command, no plan.

A robot at its goal stands while nobody comes (`prvo_planner.agent.nobody_comes`): while a plan
of the deterministic RVO baseline (model ``'rvo'``: the means, the plain radii, no inertia,
``v_pref = 0``) would stand, choosing a feasible velocity of norm at most a standing speed.
Such a plan accepts a velocity by every neighbour's alternatives ``f``, ``g``, ``h1 and h2``,
``h3`` (``moments.condition_moments`` without variance, combined as
``feasibility.combine_conditions`` does); here they are evaluated at the one velocity in
question, zero, instead of searched over every heading. Where standing still lies within a
standing speed of a condition's edge, only the plan can tell what it chooses:
:func:`standing_decided` says so, and its caller plans.
"""

import numpy as np

from .choice import INTERIOR
from .encounter import build_encounter, condition_layout
from .feasibility import combine_conditions
from .moments import condition_moments, reach_weights

# Rounding of the plan's condition polynomials, relative to their values over the speeds they
# are fitted on (a least-squares fit on a grid up to max_speed, roots, Horner's rule): generous,
# as an undecided case only costs a plan.
_ROUNDING = 1e-9


def standing_decided(ego, neighbours, config, speed):
    """
    Return whether the deterministic RVO plan of a robot with ``v_pref = 0`` stands; None: unsure.

    It stands when it is feasible and chooses a velocity of norm at most SPEED [m/s]: when no
    neighbour considered overlaps and standing still meets every one's accepted alternative on
    the means. EGO (`AgentBelief`), NEIGHBOURS (sequence of `AgentBelief`) and CONFIG
    (`PlannerConfig`, its model and inertia not used) as `plan_velocity` takes them; the
    neighbours considered are those it considers (`neighbor_distance`). None where a
    neighbour's alternative at zero is within rounding of its edge, or within what commands
    of norm SPEED change it; and where the plan's choice, kept `choice.INTERIOR` inside its
    feasible interval, could exceed SPEED. The plan decides those.
    """
    if config.max_speed * INTERIOR > speed:
        return None
    encounter = build_encounter(ego, neighbours, config)
    count = encounter.origin.shape[0]
    if count == 0:
        return True
    if encounter.overlapping.any():
        return False
    layout = condition_layout(encounter, config)
    origin, radius, lead = encounter.origin, encounter.combined_radius, encounter.lead
    # Model 'rvo' plans on the means with the plain radius (`encounter.model_moments`).
    means, _ = condition_moments(origin, np.zeros((count, 4, 4)), radius, np.zeros((1, 2)),
                                 config.time_horizon, layout.has_receding, lead)
    value = combine_conditions(means[:, 0], layout, layout.receding_enabled,
                               any_of=np.maximum, all_of=np.minimum)
    rounding = _ROUNDING * (np.abs(value) + condition_change(
        origin, radius, lead * config.max_speed * np.sqrt(2.0), config.time_horizon))
    if np.all(value > rounding):
        return True
    if np.any(value < -(rounding + condition_change(origin, radius, lead * speed,
                                                    config.time_horizon))):
        return False
    return None


def condition_change(origin, combined_radius, reach, time_horizon):
    """
    Return per neighbour a bound on how far its accepted alternative moves, shape (N,).

    Over relative velocities within REACH [m/s] (N,) of ORIGIN's (N, 4), the mean of ``z`` at
    zero command (a command ``v`` adds ``lead v``); COMBINED_RADIUS (N,) ``R``; TIME_HORIZON
    ``tau`` (inf: ``f`` and ``g`` only). Each of ``f``, ``g``, ``h1``, ``h2``, ``h3`` moves by at
    most its bound, and a maximum or minimum of them by at most the largest. With ``d = |r|``
    and ``|w|^2`` moving by at most ``spread = reach (2 |w| + reach)``:
    ``f = (r x w)^2 - R^2 |w|^2`` by ``(d^2 + R^2) spread``, ``g = r . w`` by ``d reach``,
    ``h1 = -(r . w) - tau |w|^2`` by ``d reach + tau spread``,
    ``h2 = |r + tau w|^2 - R^2`` by ``tau reach (2 |r + tau w| + tau reach)`` and
    ``h3 = (1 - eps) (d^2 - tau^2 |w|^2 / eps) - R^2`` by ``(1 - eps) / eps tau^2 spread``.
    """
    relative, velocity = origin[:, :2], origin[:, 2:]
    distance = np.hypot(relative[:, 0], relative[:, 1])
    spread = reach * (2.0 * np.hypot(velocity[:, 0], velocity[:, 1]) + reach)
    change = np.maximum((distance ** 2 + combined_radius ** 2) * spread, distance * reach)
    if np.isfinite(time_horizon):
        tau = time_horizon
        ahead = relative + tau * velocity
        weight = reach_weights(origin, combined_radius)
        change = np.maximum.reduce([
            change, distance * reach + tau * spread,
            tau * reach * (2.0 * np.hypot(ahead[:, 0], ahead[:, 1]) + tau * reach),
            (1.0 - weight) / weight * tau ** 2 * spread])
    return change
