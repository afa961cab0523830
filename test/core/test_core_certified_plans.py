"""The planner's certified mode: what it returns meets eta by sampling, and it detours less."""

import dataclasses
import math

from independent import line_clear, relative_samples
import numpy as np
from prvo_core_testing import random_two_robot_encounter
import pytest

from prvo_planner.core import AgentBelief, PlannerConfig, eta_from_k, plan_velocity

SAMPLES = 20000
# One-sided z for a family-wise false alarm below 1e-3 over the ~600 checks of this module.
Z = 4.9


def holds(rng, ego, neighbour, velocity, actuation, config):
    """Sample the planner's condition f >= 0 or g >= 0 or (h1 and h2), written out.

    f: the line of relative motion clears R; g (with the gate): the robots move apart; h1, h2
    (finite horizon): the closest approach is beyond tau and the robots are R apart at tau.
    """
    r, u = relative_samples(rng, ego, neighbour, velocity, actuation, SAMPLES)
    radius = ego.radius + neighbour.radius
    event = line_clear(r, u, radius)
    closing = np.sum(r * u, axis=1)
    if config.receding_gate:
        event |= closing >= 0.0
    tau = config.time_horizon
    if math.isfinite(tau):
        event |= ((-closing - tau * np.sum(u * u, axis=1) >= 0.0)
                  & (np.sum((r + tau * u) ** 2, axis=1) >= radius ** 2))
    return event.mean()


def tolerance(probability):
    return Z * math.sqrt(probability * (1.0 - probability) / SAMPLES)


@pytest.mark.parametrize('eta, risk, gate, horizon', [
    (0.8, 'pairwise', False, math.inf), (0.9, 'pairwise', True, math.inf),
    (0.95, 'pairwise', True, 5.0), (0.99, 'pairwise', False, math.inf),
    (0.9, 'joint', True, 5.0), (0.95, 'joint', False, math.inf)])
def test_certified_plans_meet_eta_for_every_neighbour_by_sampling(eta, risk, gate, horizon):
    rng = np.random.default_rng(int(1000 * eta) + 7 * gate + (risk == 'joint'))
    feasible = certified = below_cantelli = 0
    for _ in range(60):
        ego, first = random_two_robot_encounter(rng)
        _, second = random_two_robot_encounter(rng)
        neighbours = [first, second] if risk == 'joint' else [first]
        actuation = np.diag(rng.uniform(0.0, 0.02, size=2))
        config = PlannerConfig(eta=eta, risk=risk, receding_gate=gate, time_horizon=horizon,
                               num_directions=32, actuation_cov=actuation,
                               certificate='certified')
        # Heading at the first neighbour, so that the constraint usually binds.
        v_pref = first.position / np.hypot(*first.position) + rng.normal(0.0, 0.2, 2)
        result = plan_velocity(ego, neighbours, v_pref, config)
        if not result.feasible:
            continue
        feasible += 1
        required = 1.0 - (1.0 - eta) / len(neighbours) if risk == 'joint' else eta
        # The planner derives the joint split through k: equal to rounding.
        assert result.eta_bound >= required - 1e-12
        assert result.eta_bound == min(result.neighbour_bounds)
        certified += 'certified' in result.bound_kinds
        # Velocities Cantelli's margin rejects are returned, with their certified bound.
        below_cantelli += result.achieved_k < math.sqrt(required / (1.0 - required)) - 1e-9
        for neighbour, bound in zip(neighbours, result.neighbour_bounds, strict=True):
            assert bound >= required - 1e-12
            probability = holds(rng, ego, neighbour, result.velocity, actuation, config)
            # The bound is a lower bound on the probability, hence so is eta.
            assert probability >= bound - tolerance(bound), (probability, bound)
    print(f'eta={eta} {risk}: {feasible}/60 feasible, {certified} certified, {below_cantelli} '
          'below the Cantelli margin')
    assert feasible >= 40 and certified >= 20 and below_cantelli >= 10


def head_on(distance, std):
    """Two robots of radius 0.3 head-on at DISTANCE m, 0.8 m/s each, every std STD."""
    covariance = std ** 2 * np.eye(4)
    ego = AgentBelief([0.0, 0.0], [0.8, 0.0], covariance, 0.3)
    other = AgentBelief([distance, 0.0], [-0.8, 0.0], covariance, 0.3)
    return ego, other


@pytest.mark.parametrize('distance, eta', [(3.0, 0.8), (3.0, 0.95), (3.0, 0.99), (5.0, 0.9),
                                           (5.0, 0.99)])
def test_certified_mode_deviates_less_head_on_at_the_same_eta(distance, eta):
    ego, other = head_on(distance, 0.05)
    v_pref = np.array([1.0, 0.0])
    base = PlannerConfig(eta=eta, actuation_cov=0.0025 * np.eye(2))
    cantelli = plan_velocity(ego, [other], v_pref, base)
    certified = plan_velocity(ego, [other], v_pref,
                              dataclasses.replace(base, certificate='certified'))
    assert cantelli.feasible and certified.feasible
    # The certified velocity is closer to v_pref and makes more progress towards the goal.
    assert (np.linalg.norm(certified.velocity - v_pref)
            < np.linalg.norm(cantelli.velocity - v_pref) - 0.05)
    assert certified.velocity[0] > cantelli.velocity[0]
    # Cantelli's bound rejects it; the certified bound accepts it.
    assert certified.achieved_k < base.effective_k
    assert certified.bound_kinds == ('certified',) and certified.eta_bound >= eta
    assert cantelli.bound_kinds == ('cantelli',) and cantelli.eta_bound >= eta


def test_a_shortfall_restores_cantelli_margin_for_that_neighbour():
    # Head-on at 3 m, eta 0.9: the velocity found with the smaller margin is not certified to
    # 0.9, so the neighbour's links are searched again with Cantelli's k = 3, which gives
    # Cantelli's plan (and its certificate, above Cantelli's bound).
    ego, other = head_on(3.0, 0.05)
    base = PlannerConfig(eta=0.9, actuation_cov=0.0025 * np.eye(2))
    cantelli = plan_velocity(ego, [other], [1.0, 0.0], base)
    certified = plan_velocity(ego, [other], [1.0, 0.0],
                              dataclasses.replace(base, certificate='certified'))
    assert np.array_equal(certified.velocity, cantelli.velocity)
    assert certified.achieved_k >= base.effective_k - 1e-9
    assert certified.eta_bound >= cantelli.eta_bound >= 0.9 - 1e-12


def test_a_neighbour_cantelli_already_certifies_is_not_certified_again():
    # Head-on at 3 m at eta 0.95, and a second robot 6 m behind, driving away: the choice
    # (with the smaller search margin) falls short of Cantelli's k for the first, not for the
    # second, whose bound stays Cantelli's; both meet eta, and by sampling.
    ego, first = head_on(3.0, 0.05)
    second = AgentBelief([-6.0, 0.0], [-0.8, 0.0], 0.0025 * np.eye(4), 0.3)
    actuation = 0.0025 * np.eye(2)
    config = PlannerConfig(eta=0.95, actuation_cov=actuation, certificate='certified')
    result = plan_velocity(ego, [first, second], [1.0, 0.0], config)
    assert result.feasible and result.bound_kinds == ('certified', 'cantelli')
    assert result.achieved_k < config.effective_k
    rng = np.random.default_rng(11)
    for neighbour, bound in zip((first, second), result.neighbour_bounds, strict=True):
        assert bound >= 0.95 - 1e-12
        probability = holds(rng, ego, neighbour, result.velocity, actuation, config)
        assert probability >= bound - tolerance(bound), (probability, bound)
    # Alone with the first, the plan is the same: the second robot constrains nothing here.
    alone = plan_velocity(ego, [first], [1.0, 0.0], config)
    np.testing.assert_array_equal(alone.velocity, result.velocity)
    assert alone.neighbour_bounds[0] == result.neighbour_bounds[0]


def test_the_default_mode_reports_cantelli_bounds_per_neighbour():
    rng = np.random.default_rng(3)
    ego, first = random_two_robot_encounter(rng)
    _, second = random_two_robot_encounter(rng)
    config = PlannerConfig(eta=0.9)
    result = plan_velocity(ego, [first, second], first.position, config)
    assert config.certificate == 'cantelli' and result.certificate == 'cantelli'
    assert result.bound_kinds == ('cantelli', 'cantelli')
    assert result.eta_bound == eta_from_k(max(result.achieved_k, 0.0))
    assert min(result.neighbour_bounds) == pytest.approx(result.eta_bound, abs=1e-15)
    explicit = plan_velocity(ego, [first, second], first.position,
                             dataclasses.replace(config, certificate='cantelli'))
    assert np.array_equal(explicit.velocity, result.velocity)


def test_models_without_gaussian_beliefs_plan_as_in_cantelli_mode():
    ego, other = head_on(3.0, 0.05)
    for model in ('rvo', 'inflate'):
        config = PlannerConfig(eta=0.9, model=model)
        plain = plan_velocity(ego, [other], [1.0, 0.0], config)
        certified = plan_velocity(ego, [other], [1.0, 0.0],
                                  dataclasses.replace(config, certificate='certified'))
        assert np.array_equal(plain.velocity, certified.velocity)
        assert certified.bound_kinds == ('cantelli',)


@pytest.mark.parametrize('value', ['gaussian', '', None, 1])
def test_bad_certificate_values_are_refused_by_name(value):
    with pytest.raises(ValueError, match='PlannerConfig.certificate must be one of') as error:
        PlannerConfig(certificate=value)
    assert '\n' not in str(error.value) and repr(value) in str(error.value)


@pytest.mark.parametrize('risk, others', [('joint', 0), ('joint', 2), ('pairwise', 2)])
def test_a_robot_at_its_goal_beside_standing_neighbours_stands_still(risk, others):
    # A robot at its goal, 2.5 m from a standing neighbour (and OTHERS more at 3.5 m), moving
    # at 0.1 m/s. Standing still is slow relative motion: neither f nor g nor the horizon pair
    # holds with 0.95 alone, their union does (no contact within tau). A planner that cannot
    # see the union takes the cheapest velocity outside a disc about half its current velocity
    # (the reciprocal 2 v - v_i - v_j), opposite to it, and its commands flip every plan.
    covariance = np.diag([0.05 ** 2] * 2 + [0.07 ** 2] * 2)
    neighbours = [AgentBelief([2.5, 0.3], [0.0, 0.0], covariance, 0.35)]
    neighbours += [AgentBelief(3.5 * np.array([math.cos(2.0 + 1.3 * k), math.sin(2.0 + 1.3 * k)]),
                               [0.0, 0.0], covariance, 0.35) for k in range(others)]
    actuation = 0.0025 * np.eye(2)
    config = PlannerConfig(eta=0.95, risk=risk, certificate='certified', max_speed=0.8,
                           actuation_cov=actuation, inertia=0.5, passing_bias=0.1,
                           progress_weight=0.5)
    position, velocity = np.zeros(2), np.array([0.1, 0.0])
    commands = []
    for _ in range(20):
        ego = AgentBelief(position, velocity, covariance, 0.25)
        result = plan_velocity(ego, neighbours, -position / 0.5, config, previous=velocity)
        assert result.feasible
        commands.append(result.velocity)
        velocity = result.velocity
        position = position + 0.1 * velocity
    commands = np.array(commands)
    reversals = np.einsum('ij,ij->i', commands[1:], commands[:-1]) < 0.0
    assert not reversals.any(), commands
    assert np.all(np.hypot(*commands[5:].T) <= 0.05), commands
    assert np.hypot(*position) <= 0.05
    # Sampling agrees that the last command meets eta for every neighbour.
    required = 1.0 - 0.05 / len(neighbours) if risk == 'joint' else 0.95
    rng = np.random.default_rng(5 + others)
    for neighbour, bound in zip(neighbours, result.neighbour_bounds, strict=True):
        assert bound >= required - 1e-12
        probability = holds(rng, ego, neighbour, result.velocity, actuation, config)
        assert probability >= bound - tolerance(bound), (probability, bound)
