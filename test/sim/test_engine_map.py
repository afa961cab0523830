"""The in-process engine with a map: each agent has the grid as a node receives it, uses it."""

import inspect

import numpy as np
import pytest

from prvo_planner.core import plan_velocities
from prvo_planner.maps import GridMap
from prvo_planner.parameters import DEFAULTS
from prvo_sim import engine
from prvo_sim.engine import InProcessTeam
from prvo_sim.scenario import find_scenario, load_scenario


@pytest.fixture
def planned_obstacles(monkeypatch):
    """Record the obstacles the team's plans get; without them until the core takes them."""
    seen = []
    takes_obstacles = 'obstacles' in inspect.signature(plan_velocities).parameters

    def recording(*columns, obstacles=None):
        seen.append(obstacles)
        if obstacles is not None and takes_obstacles:
            return plan_velocities(*columns, obstacles=obstacles)
        return plan_velocities(*columns)

    monkeypatch.setattr(engine, 'plan_velocities', recording)
    return seen


def split_plane():
    """Return a 12 m x 8 m grid around headon2's robots, a wall at x = 0 open for y > 2 m."""
    cells = np.zeros((80, 120), dtype=np.int8)
    cells[:60, 59:61] = 100
    return GridMap(cells, 0.1, [-6.0, -4.0])


def team(grid_map):
    scenario = load_scenario(find_scenario('headon2'))
    values = [{**DEFAULTS, 'goal': [float(value) for value in robot.goal],
               'radius': robot.radius, 'max_speed': robot.max_speed,
               'actuation_std': robot.noise.actuation_std,
               'neighbors': [other.name for other in scenario.robots if other is not robot]}
              for robot in scenario.robots]
    return InProcessTeam(scenario, values, grid_map=grid_map)


def test_agents_get_the_grid_through_the_message_and_go_round_the_wall(planned_obstacles):
    grid = split_plane()
    robots = team(grid)
    for agent in robots.agents:
        np.testing.assert_array_equal(agent.grid_map.cells, grid.cells)
        np.testing.assert_array_equal(agent.grid_map.origin, grid.origin)
        # What the message carries: a float32 resolution.
        assert agent.grid_map.resolution == float(np.float32(0.1))
    highest = np.full(2, -np.inf)
    while not robots.finished:
        step = robots.do_step()
        assert all(command.route_status == 'ok' for command in robots.last_commands)
        highest = np.maximum(highest, step.states[:, 1])
        if all(command.arrived for command in robots.last_commands):
            break
    assert all(command.arrived for command in robots.last_commands)
    # Both went up through the opening rather than straight along y = 0.
    assert (highest > 2.0).all()
    # Beside the wall the team's plans had its faces, one entry per robot planned.
    near = [obstacles for obstacles in planned_obstacles if obstacles is not None]
    assert near and all(len(obstacles) in (1, 2) for obstacles in near)
    assert any(near is not None and len(near) > 0 for obstacles in near for near in obstacles)


def test_without_a_map_the_team_has_none():
    robots = team(None)
    robots.do_step()
    assert all(agent.grid_map is None for agent in robots.agents)
    assert all(command.route_status == 'none' for command in robots.last_commands)
