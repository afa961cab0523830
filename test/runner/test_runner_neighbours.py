"""Neighbours as they are, in process: real sizes and shares, robots that stay at their goal."""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from prvo_msgs_util import serialized_route
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import ArrivalRule, planner_values
from prvo_sim.scenario import load_scenario

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def run_inprocess(scenario, method, out_dir):
    """Run SCENARIO with METHOD on the in-process engine; return its metrics.json."""
    completed = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', str(SCENARIOS / f'{scenario}.yaml'),
         '--engine', 'inprocess', '--method', method, '--out', str(out_dir), '--quiet',
         '--no-bag', '--no-animation'],
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


# Two robots side by side, each a metre and a half from its goal: they set off and arrive.
SIDE_BY_SIDE = """\
name: side_by_side
seed: 5
dt: 0.1
duration: 5.0
goal_tolerance: 0.2
noise: {position_std: 0.05, velocity_std: 0.05, actuation_std: 0.05}
robots:
  - {name: robot_0, start: [0.0, 0.0], goal: [1.5, 0.0], radius: 0.3, max_speed: 1.0}
  - {name: robot_1, start: [0.0, 2.0], goal: [1.5, 2.0], radius: 0.3, max_speed: 1.0}
"""


def test_the_engine_gives_every_agent_the_route_the_other_published_the_step_before(
        tmp_path, monkeypatch):
    path = tmp_path / 'side_by_side.yaml'
    path.write_text(SIDE_BY_SIDE)
    scenario = load_scenario(path)
    published = []
    give_route = InProcessTeam._give_route

    def recorded(team, index, sent):
        published.append((team.world.names[index], team.world.time, sent))
        give_route(team, index, sent)

    monkeypatch.setattr(InProcessTeam, '_give_route', recorded)
    team = InProcessTeam(scenario, [planner_values(robot, scenario, 'prvo', None, 'lockstep')
                                    for robot in scenario.robots])
    # Per robot, what its neighbour is to hold of its route: (points, stamp), None for none.
    held = {name: None for name in team.world.names}
    while not team.finished:
        step_time = team.world.time
        team.do_step()
        for request in team.last_requests:
            (other,) = request.neighbour_names
            (route,) = request.neighbour_routes
            # What the other published after its plans of the steps before this one.
            if held[other] is None:
                assert route is None, step_time
            else:
                assert (route.points.tolist(), route.stamp) == held[other], step_time
        for robot, published_time, sent in published:
            if published_time == step_time:
                stamp, waypoints = serialized_route(sent)
                # Stamped with the plan's stamp (1 ns for the plan of stamp 0).
                assert stamp == max(step_time, 1e-9)
                held[robot] = (waypoints.tolist(), stamp)
    # Each set off (the straight way from where it stood) and arrived (its goal alone).
    for robot, goal in (('robot_0', [1.5, 0.0]), ('robot_1', [1.5, 2.0])):
        routes = [serialized_route(sent)[1].tolist() for name, _, sent in published
                  if name == robot]
        assert len(routes) == 2 and routes[0][1] == goal and routes[1] == [goal], routes
