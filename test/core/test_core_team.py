"""``plan_velocities`` plans each robot of a team bit for bit as ``plan_velocity`` does alone."""

import dataclasses

import numpy as np
from prvo_core_testing import random_covariance
import pytest

from prvo_planner.bench import circle_swap, same_plan, team_config
from prvo_planner.core import (
    AgentBelief,
    PlannerConfig,
    VelocityLimits,
    plan_velocities,
    plan_velocity,
)
from prvo_planner.core import planner as planner_module


def assert_each_as_alone(egos, neighbours, v_prefs, configs, previous):
    """Plan the team at once and every robot alone; every result must be identical."""
    team = plan_velocities(egos, neighbours, v_prefs, configs, previous)
    assert len(team) == len(egos)
    for index, result in enumerate(team):
        config = configs if isinstance(configs, PlannerConfig) else configs[index]
        alone = plan_velocity(egos[index], neighbours[index], v_prefs[index], config,
                              previous[index])
        assert same_plan(result, alone), (index, result, alone)
    return team


@pytest.mark.parametrize('count', [3, 7, 12])
def test_circle_swap_steps_are_planned_as_alone(count):
    # Every 7th step of a closed loop: approach, the crowded centre, departure, arrival.
    config = team_config()
    checked = 0
    for step, (egos, neighbours, v_prefs, previous) in enumerate(circle_swap(count, config)):
        if step % 7 == 0:
            assert_each_as_alone(egos, neighbours, v_prefs, config, previous)
            checked += 1
    assert checked >= 5


def test_a_team_split_into_batches_is_planned_as_alone(monkeypatch):
    # A crowd is solved in batches of at most LINK_BATCH links: here two robots (704 links
    # each, 11 neighbours and 64 directions) a call.
    monkeypatch.setattr(planner_module, 'LINK_BATCH', 2000)
    config = dataclasses.replace(team_config(), certificate='certified', eta=0.95)
    calls = []
    solve_group = planner_module._solve_group
    monkeypatch.setattr(planner_module, '_solve_group',
                        lambda plans: calls.append(len(plans)) or solve_group(plans))
    for step, (egos, neighbours, v_prefs, previous) in enumerate(circle_swap(12, config)):
        if step % 13 == 0:
            assert_each_as_alone(egos, neighbours, v_prefs, config, previous)
    assert max(calls) > 1 and min(calls) < 12


def test_certified_circle_swap_steps_are_planned_as_alone():
    # Certificates are computed per robot, so a robot's shortfalls and retries are its own.
    config = dataclasses.replace(team_config(), certificate='certified', eta=0.95)
    checked = 0
    for step, (egos, neighbours, v_prefs, previous) in enumerate(circle_swap(6, config)):
        if step % 11 == 0:
            team = assert_each_as_alone(egos, neighbours, v_prefs, config, previous)
            checked += any('certified' in result.bound_kinds for result in team)
    assert checked >= 3


def test_robots_of_other_horizons_neighbours_and_directions_are_planned_as_alone():
    # One call solves robots whose time horizons (shortened near their goals), numbers of
    # neighbours and numbers of candidate directions (acceleration limits add some) differ.
    rng = np.random.default_rng(11)
    base = team_config()
    checked = 0
    for step, (egos, neighbours, v_prefs, previous) in enumerate(circle_swap(8, base)):
        if step % 9:
            continue
        configs = [dataclasses.replace(base, time_horizon=float(rng.uniform(0.5, 5.0)))
                   for _ in egos]
        subsets = [[other for other in group if rng.uniform() < 0.7] for group in neighbours]
        limits = [VelocityLimits(current=0.5 * rng.normal(size=2), max_change=0.1)
                  if rng.uniform() < 0.5 else None for _ in egos]
        assert len({len(group) for group in subsets}) > 1
        team = plan_velocities(egos, subsets, v_prefs, configs, previous, limits)
        for index, result in enumerate(team):
            alone = plan_velocity(egos[index], subsets[index], v_prefs[index], configs[index],
                                  previous[index], limits[index])
            assert same_plan(result, alone), (step, index, result, alone)
        checked += 1
    assert checked >= 5


def random_team(rng, count, spread):
    """Robots in a ``spread`` m box with random velocities, covariances and radii."""
    egos = []
    for _ in range(count):
        noise = rng.choice([0.0, 0.02, 0.1])
        covariance = random_covariance(rng, 4, noise) if noise else np.zeros((4, 4))
        egos.append(AgentBelief(rng.uniform(-spread, spread, size=2),
                                rng.uniform(-1.0, 1.0, size=2) * rng.choice([0.0, 1.0]),
                                covariance, rng.uniform(0.2, 0.4)))
    return egos


def random_config(rng):
    """Draw a configuration of any model, method, horizon, risk and cost terms."""
    model = rng.choice(['prvo', 'prvo', 'rvo', 'inflate', 'mc'])
    return PlannerConfig(
        eta=rng.uniform(0.5, 0.95), max_speed=rng.choice([0.8, 1.0, 1.5]),
        num_directions=int(rng.choice([8, 16, 64])),
        time_horizon=rng.choice([2.0, 5.0, np.inf]),
        neighbor_distance=rng.choice([1.0, 10.0]),
        actuation_cov=rng.uniform(0.0, 0.01) * np.eye(2),
        method=rng.choice(['exact', 'taylor']),
        model=model,
        risk=rng.choice(['pairwise', 'joint']), receding_gate=bool(rng.integers(2)),
        # Unseeded Monte Carlo plans differ from call to call by design.
        mc_samples=50, seed=int(rng.integers(3)) if model == 'mc' or rng.integers(2) else None,
        inertia=rng.choice([0.0, 0.5]), passing_bias=rng.choice([0.0, 0.1]),
        certificate=rng.choice(['cantelli', 'certified']))


@pytest.mark.parametrize('seed', range(40))
def test_mixed_teams_are_planned_as_alone(seed):
    # Mixed models and methods, one shared or one configuration per robot, neighbour subsets
    # of different sizes (some empty or out of range), crowded boxes where nothing is
    # feasible, robots at rest and without a previous command.
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 9))
    egos = random_team(rng, count, rng.choice([1.0, 3.0, 8.0]))
    neighbours = [[other for other in egos if other is not ego and rng.uniform() < 0.8]
                  for ego in egos]
    shared = rng.uniform() < 0.5
    configs = random_config(rng) if shared else [random_config(rng) for _ in range(count)]
    v_prefs = [rng.normal(size=2) * rng.choice([0.0, 1.0]) for _ in range(count)]
    previous = [rng.normal(size=2) if rng.uniform() < 0.7 else None for _ in range(count)]
    assert_each_as_alone(egos, neighbours, v_prefs, configs, previous)


def test_companions_and_order_do_not_change_a_plan():
    rng = np.random.default_rng(7)
    config = team_config()
    egos = random_team(rng, 9, 3.0)
    neighbours = [[other for other in egos if other is not ego] for ego in egos]
    v_prefs = [rng.normal(size=2) for _ in egos]
    previous = [rng.normal(size=2) for _ in egos]
    full = plan_velocities(egos, neighbours, v_prefs, config, previous)
    order = rng.permutation(len(egos))
    shuffled = plan_velocities([egos[i] for i in order], [neighbours[i] for i in order],
                               [v_prefs[i] for i in order], config,
                               [previous[i] for i in order])
    for position, index in enumerate(order):
        assert same_plan(shuffled[position], full[index])
    halves = (plan_velocities(egos[:4], neighbours[:4], v_prefs[:4], config, previous[:4])
              + plan_velocities(egos[4:], neighbours[4:], v_prefs[4:], config, previous[4:]))
    assert all(same_plan(a, b) for a, b in zip(halves, full, strict=True))


def test_infeasible_team_members_fall_back_as_alone():
    # Robots packed closer than their radii: every plan is infeasible and ranks candidates.
    rng = np.random.default_rng(3)
    egos = [AgentBelief(rng.uniform(-0.3, 0.3, size=2), rng.uniform(-1.0, 1.0, size=2),
                        random_covariance(rng, 4, 0.05), 0.3) for _ in range(6)]
    neighbours = [[other for other in egos if other is not ego] for ego in egos]
    config = team_config()
    team = assert_each_as_alone(egos, neighbours, [np.array([1.0, 0.0])] * 6, config,
                                [None] * 6)
    assert not any(result.feasible for result in team)


def test_bad_team_inputs_name_the_robot():
    ego = AgentBelief([0.0, 0.0], [0.0, 0.0], np.eye(4) * 0.01, 0.3)
    other = AgentBelief([2.0, 0.0], [0.0, 0.0], np.eye(4) * 0.01, 0.3)
    config = PlannerConfig()
    with pytest.raises(ValueError, match=r'v_prefs must have one entry per ego \(2\), got 1'):
        plan_velocities([ego, other], [[other], [ego]], [[1.0, 0.0]], config)
    with pytest.raises(ValueError, match=r'robot 1: v_pref must have shape \(2,\)'):
        plan_velocities([ego, other], [[other], [ego]], [[1.0, 0.0], [1.0]], config)
    with pytest.raises(ValueError, match=r'robot 0: neighbours\[0\] must be an AgentBelief'):
        plan_velocities([ego], [['robot_1']], [[1.0, 0.0]], config)
    assert plan_velocities([], [], [], config) == []
