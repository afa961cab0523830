"""The map's walls bind in every preferred source: a filtered command, a followed path.

A robot told to drive into a wall, by an upstream command (velocity mode) or by a path that
runs through the wall (path mode), stops short of it when its planner has the map, and goes
through it without one. The distances are the test's own: to the wall's face, from the cells.
"""

import dataclasses

import numpy as np
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.maps import GridMap
from prvo_planner.preferred import UpstreamCommand

RESOLUTION = 0.05
RADIUS = 0.3
# The wall's face toward the robot [m]: cells of x in [2, 2.2) are occupied.
WALL_FACE = 2.0
CONFIG = PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=1e-4 * np.eye(2))
CERTIFICATES = ('cantelli', 'certified')
DT = 0.1


@dataclasses.dataclass(frozen=True)
class _Measurement:
    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


def _walled_grid():
    """Return a 6 m x 6 m grid from (-2, -3) with a wall of x in [2, 2.2), y in [-2, 2]."""
    cells = np.zeros((120, 120), dtype=np.int8)
    columns = slice(int(round((WALL_FACE + 2.0) / RESOLUTION)),
                    int(round((WALL_FACE + 2.2) / RESOLUTION)))
    cells[int(round(1.0 / RESOLUTION)):int(round(5.0 / RESOLUTION)), columns] = 100
    return GridMap(cells, RESOLUTION, [-2.0, -3.0])


def _clearance(grid, position):
    """Return the distance [m] from POSITION to the nearest occupied cell, from the cells."""
    rows, columns = np.nonzero(grid.cells > 0)
    low = grid.origin + RESOLUTION * np.stack([columns, rows], axis=1)
    nearest = np.clip(position, low, low + RESOLUTION)
    return float(np.min(np.linalg.norm(nearest - position, axis=1)))


def _agent(source, grid, certificate='cantelli', **settings):
    config = dataclasses.replace(CONFIG, certificate=certificate)
    agent = PlannerAgent('robot_0', config, AgentSettings(
        radius=RADIUS, preferred_source=source, goal_tolerance=0.1, **settings))
    if grid is not None:
        agent.set_map(grid)
    return agent


def _drive(agent, steps, upstream=None):
    """Move a noise-free robot from the origin by its commands; return its positions (S, 2)."""
    position, velocity = np.zeros(2), np.zeros(2)
    positions = [position]
    for step in range(steps):
        agent.receive_own(_Measurement(round(step * DT, 9), position, velocity,
                                       1e-4 * np.eye(4)), step * DT)
        if upstream is not None:
            agent.receive_upstream(UpstreamCommand(upstream, 0.0), step * DT)
        command = agent.plan()
        velocity = (np.array(command.upstream.linear) if command.passed_through
                    else command.velocity)
        position = position + DT * velocity
        positions.append(position)
    return np.array(positions)


@pytest.mark.parametrize('certificate', CERTIFICATES)
@pytest.mark.parametrize('source', ['velocity', 'path'])
def test_a_command_into_a_wall_stops_short_of_it_with_the_map(source, certificate):
    grid = _walled_grid()
    upstream = (0.8, 0.0) if source == 'velocity' else None
    # A robot alone by a wall: its plans have no neighbour's bound (certified or Cantelli's).
    with_map = _agent(source, grid, certificate)
    without_map = _agent(source, None, certificate)
    if source == 'path':
        # Straight through the wall to a point beyond it.
        for agent in (with_map, without_map):
            agent.set_path(np.array([[0.0, 0.0], [2.0, 0.0], [3.5, 0.0]]))
    positions = _drive(with_map, 60, upstream)
    clearances = [_clearance(grid, position) for position in positions]
    assert min(clearances) >= RADIUS - 1e-6
    # It came up to the wall rather than stopping anywhere.
    assert positions[-1][0] > WALL_FACE - RADIUS - 0.3
    blind = _drive(without_map, 60, upstream)
    assert blind[:, 0].max() > WALL_FACE + 0.2


def test_a_command_along_a_wall_passes_unchanged():
    grid = _walled_grid()
    agent = _agent('velocity', grid)
    position = np.array([1.0, -1.0])
    agent.receive_own(_Measurement(0.0, position, np.array([0.0, 0.5]), 1e-4 * np.eye(4)), 0.0)
    upstream = UpstreamCommand((0.0, 0.5), 0.2)
    agent.receive_upstream(upstream, 0.0)
    command = agent.plan()
    assert command.passed_through and command.upstream is upstream
