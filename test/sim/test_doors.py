"""A robot alone at a door it fits through, on the in-process engine (issue 37)."""

import math

import numpy as np
import pytest

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

# The wall's thickness [m]; its jambs' rounded ends are the door's edges.
THICKNESS = 0.1
# Half the wall's length and the start's and goal's distance from the door [m].
WALL_HALF, APPROACH = 4.0, 3.0
DURATION = 30.0


def door_scenario(tmp_path, radius, clear_width, noise, angle=0.0, eta=None):
    """Write a one-robot scenario: a wall along x = 0 with a door centred at the origin.

    The door's clear width is the distance between the jambs' surfaces; the robot starts
    APPROACH from the door's centre at ANGLE [rad] from the wall's normal and heads for the
    point opposite.
    """
    tip = 0.5 * clear_width + 0.5 * THICKNESS
    heading = np.array([math.cos(angle), math.sin(angle)])
    start, goal = -APPROACH * heading, APPROACH * heading
    planner = '' if eta is None else f'planner:\n  eta: {eta}\n'
    text = f"""name: door
description: One robot, one door.
seed: 1
dt: 0.1
duration: {DURATION}
goal_tolerance: 0.2
noise:
  position_std: {noise}
  velocity_std: {noise}
  actuation_std: {noise}
{planner}walls:
  - line: [[0.0, {WALL_HALF}], [0.0, {tip}]]
    thickness: {THICKNESS}
  - line: [[0.0, {-WALL_HALF}], [0.0, {-tip}]]
    thickness: {THICKNESS}
robots:
  - name: robot_0
    start: [{start[0]:.6f}, {start[1]:.6f}]
    goal: [{goal[0]:.6f}, {goal[1]:.6f}]
    radius: {radius}
    max_speed: 1.0
"""
    path = tmp_path / 'door.yaml'
    path.write_text(text)
    return path


def through_the_door(path, seed):
    """Run PATH in process; return (seconds until the robot is past the wall or None, contacts).

    Past the wall: its centre beyond the wall's far face by its radius (the test's own
    geometry, from the ground truth).
    """
    scenario = load_scenario(path, seed=seed)
    values = [planner_values(robot, scenario, 'prvo', None) for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    radius = scenario.robots[0].radius
    contacts = 0
    while not team.finished:
        step = team.do_step()
        contacts += len(team.world.last_wall_contacts)
        if step.states[0, 0] > 0.5 * THICKNESS + radius:
            return step.time, contacts
    return None, contacts


@pytest.mark.xfail(strict=True, reason='issue 37: the wall condition asks for ~0.2 m beside '
                                       'the jambs where 3 position stds are 0.15 m')
def test_a_robot_alone_passes_a_door_three_position_stds_wider_on_each_side(tmp_path):
    # Radius 0.3, noise 0.05, planner defaults: a 0.9 m door leaves 0.15 m on each side.
    path = door_scenario(tmp_path, radius=0.3, clear_width=0.9, noise=0.05)
    passed, contacts = through_the_door(path, seed=1)
    assert contacts == 0
    assert passed is not None
