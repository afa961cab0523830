"""A robot alone at a door it fits through, on the in-process engine (issue 37)."""

import math

import pytest

from prvo_sim.bench.doors import door_scenario, run_door


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
    passed, contacts, clearance = run_door(path, seed)
    assert contacts == 0
    assert clearance > 0.0
    assert passed is not None
