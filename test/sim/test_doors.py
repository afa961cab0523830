"""A robot alone at a door or in a corridor it fits through, in process (issue 37)."""

import math

import pytest

from prvo_sim.bench.doors import (
    at_the_goal,
    corridor_scenario,
    door_scenario,
    past_the_door,
    run_alone,
)


@pytest.mark.parametrize(('radius', 'sigma', 'eta', 'angle_deg', 'seed'), [
    # The case: radius 0.3, noise 0.05, defaults, a 0.9 m door.
    (0.3, 0.05, None, 0.0, 1),
    (0.25, 0.05, 0.99, 45.0, 2),
    (0.2, 0.02, 0.99, 0.0, 3),
    (0.3, 0.02, 0.95, 45.0, 4),
])
def test_a_robot_alone_passes_a_door_three_position_stds_wider_on_each_side(
        tmp_path, radius, sigma, eta, angle_deg, seed):
    width = 2.0 * radius + 6.0 * sigma
    path = tmp_path / 'door.yaml'
    path.write_text(door_scenario(radius, width, sigma, math.radians(angle_deg), eta))
    passed, contacts, clearance = run_alone(path, seed, past_the_door)
    assert contacts == 0
    assert clearance > 0.0
    assert passed is not None


@pytest.mark.parametrize(('radius', 'sigma', 'eta', 'seed'), [
    # The robot at the defaults, and the narrowest corridor (0.52 m) at eta 0.99.
    (0.3, 0.05, None, 1),
    (0.2, 0.02, 0.99, 2),
])
def test_a_robot_alone_drives_an_l_shaped_corridor_three_position_stds_wider_on_each_side(
        tmp_path, radius, sigma, eta, seed):
    path = tmp_path / 'corridor.yaml'
    path.write_text(corridor_scenario(radius, 2.0 * radius + 6.0 * sigma, sigma, eta))
    arrived, contacts, clearance = run_alone(path, seed, at_the_goal)
    assert contacts == 0
    assert clearance > 0.0
    assert arrived is not None
