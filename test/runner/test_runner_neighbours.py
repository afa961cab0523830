"""Neighbours as they are, in process: real sizes and shares, robots that stay at their goal."""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import ArrivalRule, planner_values
from prvo_sim.scenario import load_scenario

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def run_inprocess(scenario, method, out_dir):
    """Run SCENARIO with METHOD on the in-process engine; return its metrics.json."""
    completed = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', str(SCENARIOS / f'{scenario}.yaml'),
         '--engine', 'inprocess', '--method', method, '--out', str(out_dir), '--quiet'],
        capture_output=True, text=True, timeout=900)
    assert completed.returncode == 0, completed.stderr
    return json.loads((out_dir / 'metrics.json').read_text())


def test_the_engine_gives_every_agent_what_the_others_announce():
    scenario = load_scenario(SCENARIOS / 'parked_large.yaml')
    team = InProcessTeam(scenario, [planner_values(robot, scenario, 'prvo', None, 'lockstep')
                                    for robot in scenario.robots])
    radii = {robot.name: robot.radius for robot in scenario.robots}
    for agent in team.agents:
        for name, radius in radii.items():
            if name != agent.name:
                announced = agent.announcement_of(name, 0.0)
                # Through the footprint message: single precision, as a planner node reads it.
                assert announced.radius == pytest.approx(radius, rel=1e-7)
                assert announced.avoidance_share == 0.5
    # The large robot starts at its goal: once its plan finds it there, it stands and
    # announces no share (its planner's tolerance is tighter than the position noise).
    large = team.agents[0]
    for _ in range(50):
        team.do_step()
        if large.arrived:
            break
    assert large.arrived

    def shares_planned_with(robot):
        """Return the share of ROBOT each other robot's plan of the last step took."""
        return [planned.avoidance_share for command in team.last_commands
                for name, planned in zip(command.neighbour_names, command.announcements,
                                         strict=True) if name == robot]

    # As in lockstep: what it announced with this step's plan counts from the next step on.
    assert shares_planned_with('large') == [0.5] * (len(team.agents) - 1)
    team.do_step()
    assert shares_planned_with('large') == [0.0] * (len(team.agents) - 1)
    assert shares_planned_with('small_0') == [0.5] * (len(team.agents) - 1)


def test_small_robots_cross_a_large_parked_robot_without_contact(tmp_path):
    metrics = run_inprocess('parked_large', 'prvo', tmp_path)
    assert metrics['collisions'] == 0 and metrics['min_separation'] > 0.0
    assert metrics['success_rate'] == 1.0 and metrics['ending'] == 'arrived'


def test_a_mixed_team_gets_every_robot_home_in_time_without_contact(tmp_path):
    metrics = run_inprocess('mixed12', 'prvo', tmp_path)
    assert metrics['collisions'] == 0 and metrics['success_rate'] == 1.0
    for robot in load_scenario(SCENARIOS / 'mixed12.yaml').robots:
        straight = float(np.linalg.norm(robot.goal - robot.start)) / robot.max_speed
        assert metrics['robots'][robot.name]['time_to_goal'] <= 2.0 * straight + 4.0, robot.name


@pytest.mark.parametrize('arrivals, ends_at', [
    # Both at their goal from t = 1 on: the run ends at t = 1 + SETTLE_TIME = 2.
    ([[False, True], [True, True], [True, True], [True, True]], 2.0),
    # Robot 0 arrives at t = 1, is pushed aside at t = 2 and back at t = 3: counted from 3.
    ([[False, True], [True, True], [False, True], [True, True], [True, True]], 4.0),
    # Never all at once.
    ([[True, False], [False, True], [True, False], [False, True]], None)])
def test_a_run_ends_once_every_robot_is_at_its_goal_together(arrivals, ends_at):
    goals = np.array([[1.0, 0.0], [0.0, 1.0]])
    rule = ArrivalRule(goals, goal_tolerance=0.2, planned=[True, True])
    away = np.array([0.5, 0.0])  # farther than the tolerance
    ended = [float(time) for time, arrived in enumerate(arrivals) if rule.step(
        float(time), goals + np.where(np.array(arrived)[:, None], 0.0, away))]
    assert (ended[0] if ended else None) == ends_at
