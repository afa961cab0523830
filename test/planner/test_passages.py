"""Narrow passages: widths against the geometry, the certifiable width against its definition.

And a robot alone in front of a door narrower than it can certify: it holds, and its stall is
reported with the door's width and the width it needs (issue 37).
"""

import pathlib

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import norm

from prvo_planner.core import AgentBelief, PlannerConfig
from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.core.walls import certifiable_width
from prvo_planner.passages import STEP, clear_width, way_width
from prvo_planner.reports import passage_message, stall_values
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario


def _walls(segments, half_widths=None):
    segments = np.array(segments, dtype=float).reshape(-1, 2, 2)
    return StaticObstacles(segments, np.zeros(len(segments)) if half_widths is None
                           else np.array(half_widths, dtype=float), np.zeros((0, 2)),
                           np.zeros(0))


def test_the_clear_width_is_the_gap_between_the_walls_within_a_step():
    # A corridor along x between capsules 0.1 thick whose surfaces are at y = -0.3 and 0.45.
    corridor = _walls([[[-5.0, -0.35], [5.0, -0.35]], [[-5.0, 0.5], [5.0, 0.5]]], [0.05, 0.05])
    for direction in ([1.0, 0.0], [-2.0, 0.0]):
        assert abs(clear_width(corridor, [0.3, 0.1], direction) - 0.75) <= STEP
    # Across a slanted way the width is measured across it: 0.75 / cos(30 deg).
    slanted = clear_width(corridor, [0.3, 0.1], [np.cos(np.pi / 6), np.sin(np.pi / 6)])
    assert abs(slanted - 0.75 / np.cos(np.pi / 6)) <= 2.0 * STEP
    # One side open: no passage; inside a wall: none either.
    assert clear_width(_walls([[[-5.0, 0.5], [5.0, 0.5]]]), [0.0, 0.0], [1.0, 0.0]) == np.inf
    assert clear_width(corridor, [0.0, 0.5], [1.0, 0.0]) == 0.0


def test_the_width_of_a_way_is_that_of_the_widest_free_strip_along_it():
    # Slanted walls 0.1 thick on either side of the way and a pillar near it, seeded, against
    # a raster of the way's strip (5 mm cells): the nearest occupied cells on either side.
    generator = np.random.default_rng(3)
    for _ in range(40):
        low, high = generator.uniform(0.3, 0.9, 2), generator.uniform(0.3, 0.9, 2)
        segments = np.array([[[-2.0, -low[0]], [3.0, -low[1]]], [[-2.0, high[0]], [3.0, high[1]]]])
        centre, radius = generator.uniform([-0.5, -1.0], [1.5, 1.0]), generator.uniform(0.05, 0.2)
        obstacles = StaticObstacles(segments, np.array([0.05, 0.05]), centre[None],
                                    np.array([radius]))
        point, length = generator.uniform(-0.2, 0.2, 2), generator.uniform(0.3, 1.0)
        along, across = np.meshgrid(np.arange(0.0, length, 0.005), np.arange(-2.0, 2.0, 0.005))
        cells = np.stack([point[0] + along.ravel(), point[1] + across.ravel()], axis=1)
        occupied = np.hypot(*(cells - centre).T) <= radius
        for (start, end) in segments:
            t = np.clip((cells - start) @ (end - start) / np.sum((end - start) ** 2), 0.0, 1.0)
            occupied |= np.hypot(*(cells - start - t[:, None] * (end - start)).T) <= 0.05
        offsets = across.ravel()[occupied]
        expected = (np.min(offsets[offsets > 0.0], initial=np.inf)
                    - np.max(offsets[offsets < 0.0], initial=-np.inf))
        width = way_width(obstacles, point, [1.0, 0.0], length)
        if np.any(np.abs(offsets) < 0.005):
            assert width == 0.0
        else:
            # The raster's cells reach at most a cell past a surface on each side; a wall's
            # end counted a half-width early only narrows the way.
            assert expected - STEP <= width <= expected + 1e-9


def test_the_width_over_a_way_finds_a_door_thinner_than_its_spacing():
    # A wall 0.1 thick across the way 0.5 m ahead, with a door 0.9 m wide in it: at the
    # robot and 1 m ahead the sides are open.
    wall = _walls([[[0.5, 0.5], [0.5, 4.0]], [[0.5, -0.5], [0.5, -4.0]]], [0.05, 0.05])
    assert clear_width(wall, [0.0, 0.0], [1.0, 0.0]) == np.inf
    assert clear_width(wall, [1.0, 0.0], [1.0, 0.0]) == np.inf
    assert way_width(wall, [0.0, 0.0], [1.0, 0.0], 1.0) == pytest.approx(0.9)
    # Short of the door, or beyond it, the way is open; across the wall, shut.
    assert way_width(wall, [0.0, 0.0], [1.0, 0.0], 0.4) == np.inf
    assert way_width(wall, [0.0, 0.0], [-1.0, 0.0], 1.0) == np.inf
    assert way_width(wall, [0.0, 1.0], [1.0, 0.0], 1.0) == 0.0


@pytest.mark.parametrize('sigma, eta', [(0.02, 0.95), (0.05, 0.95), (0.05, 0.99)])
def test_the_certifiable_width_leaves_the_margin_whose_crossing_bound_is_the_risk(sigma, eta):
    """Independently: the reflection principle's bound for a walk without drift, solved."""
    radius, period, horizon = 0.3, 0.1, 2.0
    ego = AgentBelief(np.zeros(2), np.zeros(2), sigma ** 2 * np.eye(4), radius)
    config = PlannerConfig(eta=eta, actuation_cov=sigma ** 2 * np.eye(2),
                           obstacle_horizon=horizon, control_period=period)
    spread = np.sqrt(sigma ** 2 + period * sigma ** 2 * horizon)
    t0 = sigma ** 2 / (period * sigma ** 2)
    # No drift: P(min y < 0) <= Phi(-m / S) + Phi(-u), u = m / S (x0 = m at time -t0).
    margin = brentq(lambda m: 2.0 * norm.cdf(-m / spread) - (1.0 - eta), 0.0, 1.0)
    assert t0 > 0.0
    assert certifiable_width(ego, config) == pytest.approx(2.0 * (radius + margin), abs=1e-5)
    # Planning on the means, only the radius (and the safety margin) counts.
    means = PlannerConfig(eta=eta, model='rvo', safety_margin=0.05)
    assert certifiable_width(ego, means) == pytest.approx(2.0 * (radius + 0.05))


def _two_rooms(width, noise=0.05):
    """Return the YAML of two 4 m rooms joined by a door of clear WIDTH, a robot of r 0.3.

    NOISE: every std of the world (position, velocity, actuation).
    """
    tip = 0.5 * width + 0.05
    walls = [((0.0, tip), (0.0, 2.0)), ((0.0, -tip), (0.0, -2.0)), ((-4.0, 2.0), (4.0, 2.0)),
             ((-4.0, -2.0), (4.0, -2.0)), ((-4.0, -2.0), (-4.0, 2.0)), ((4.0, -2.0), (4.0, 2.0))]
    lines = ''.join(f'  - line: [[{a[0]}, {a[1]}], [{b[0]}, {b[1]}]]\n    thickness: 0.1\n'
                    for a, b in walls)
    return (f'name: two_rooms\ndescription: Two rooms joined by a door of {width} m.\nseed: 1\n'
            f'dt: 0.1\nduration: 30.0\ngoal_tolerance: 0.2\nnoise:\n  position_std: {noise}\n'
            f'  velocity_std: {noise}\n  actuation_std: {noise}\n'
            f'walls:\n{lines}robots:\n  - name: robot_0\n    start: [-3.0, 0.0]\n'
            '    goal: [3.0, 0.0]\n    radius: 0.3\n    max_speed: 1.0\n')


def _run_at_door(tmp_path, width, seconds, noise=0.05):
    path = pathlib.Path(tmp_path) / 'door.yaml'
    path.write_text(_two_rooms(width, noise))
    scenario = load_scenario(path, seed=1)
    team = InProcessTeam(scenario, [planner_values(robot, scenario, 'prvo', None)
                                    for robot in scenario.robots], seed=1)
    passages = []
    while team.world.time < seconds:
        team.do_step()
        command = team.last_commands[0]
        if command.narrow_passage is not None:
            passages.append(command)
    return team, passages


def test_a_robot_in_front_of_a_door_too_narrow_holds_and_says_how_wide_it_must_be(tmp_path):
    # 0.76 m for a robot of radius 0.3 and noise 0.08: the route fits (the map's cells keep
    # 0.7 m of it), certifying the way through does not (it needs 0.74 m; with noise 0.05 the
    # robot goes through a 0.72 m door).
    team, passages = _run_at_door(tmp_path, 0.76, 16.0, noise=0.08)
    assert team.world.positions[0][0] < 0.0, 'the robot went through'
    assert passages, 'no narrow passage reported'
    command = passages[0]
    passage = command.narrow_passage
    # The map the planner reads loses up to a cell (0.05 m) on each side of the door.
    assert 0.66 - STEP <= passage.width < passage.needed and passage.width <= 0.76 + STEP
    assert abs(passage.point[0]) <= 0.1 and abs(passage.point[1]) <= 0.1
    assert command.stall.began and command.stall.stalled
    assert passage_message(passage).endswith(f'needs at least {passage.needed:.2f} m (holding)')
    assert stall_values(command)['passage_width'] == passage.width


def test_a_robot_at_a_door_it_fits_reports_no_narrow_passage(tmp_path):
    team, passages = _run_at_door(tmp_path, 0.9, 8.0)
    assert team.world.positions[0][0] > 0.3 and not passages
