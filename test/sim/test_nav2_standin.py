"""Teams driven by the Nav2 stand-in: blind pure pursuit collides, the PRVO filter keeps apart.

In-process engine (the same agents and stand-in logic as the ROS lockstep run), ten seeds.
"""

import math

import numpy as np
import pytest

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import find_scenario, load_scenario
from prvo_sim.upstream import PurePursuitUpstream

SEEDS = range(10)
HELD_LIMIT = 10.0  # s a robot may stand still before its goal


def _run(name, method, seed):
    """Return (contacts, arrived (N,), longest stand before the goal [s]) of one run."""
    scenario = load_scenario(find_scenario(name), seed=seed)
    team = InProcessTeam(scenario, [planner_values(robot, scenario, method, None)
                                    for robot in scenario.robots], seed=seed)
    goals = team.world.goals
    contacts, standing, held = 0, np.zeros(len(goals)), 0.0
    arrived = np.zeros(len(goals), dtype=bool)
    while not team.finished and not arrived.all():
        step = team.do_step()
        contacts += len(step.contacts)
        arrived |= np.linalg.norm(step.states[:, :2] - goals, axis=1) <= scenario.goal_tolerance
        moving = np.linalg.norm(step.states[:, 2:4], axis=1) > 0.01
        standing = np.where(moving | arrived, 0.0, standing + scenario.dt)
        held = max(held, float(standing.max()))
    return contacts, arrived, held


@pytest.mark.parametrize('name', ['nav2_headon2', 'nav2_crossing4'])
def test_blind_upstream_collides_without_avoidance(name):
    contacts, arrived, _ = _run(name, 'none', 0)
    assert contacts > 0


@pytest.mark.parametrize('name', ['nav2_headon2', 'nav2_crossing4'])
def test_the_filter_keeps_them_apart(name):
    for seed in SEEDS:
        contacts, arrived, held = _run(name, 'prvo', seed)
        assert contacts == 0, seed
        assert arrived.all(), seed
        assert held <= HELD_LIMIT, seed


def test_stand_in_ramps_to_zero_and_turns_onto_the_path():
    upstream = PurePursuitUpstream([[0.0, 0.0], [4.0, 0.0]], 0.8, goal_tolerance=0.1,
                                   deceleration=1.0)
    assert upstream.command([0.0, 0.0], 0.0) == ((0.8, 0.0), 0.0)
    # 0.125 m before the end: braking at 1 m/s^2 allows sqrt(2 * 0.125) = 0.5 m/s.
    (forward, sideways), _ = upstream.command([3.875, 0.0], 0.0)
    assert forward == pytest.approx(0.5) and sideways == pytest.approx(0.0, abs=1e-12)
    assert upstream.command([3.95, 0.0], 0.0) == ((0.0, 0.0), 0.0)
    unicycle = PurePursuitUpstream([[0.0, 0.0], [4.0, 0.0]], 0.8, 'unicycle',
                                   max_angular_speed=10.0)
    # 0.3 m left of the path with a 0.6 m lookahead: the carrot is 30 degrees right.
    (forward, _), turn = unicycle.command([1.0, 0.3], 0.0)
    alpha = -math.asin(0.5)
    assert turn == pytest.approx(forward * 2.0 * math.sin(alpha) / 0.6)
    # The carrot behind: turn in place.
    assert unicycle.command([1.0, 0.0], math.pi)[0] == (0.0, 0.0)
