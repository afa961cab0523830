"""Walls, obstacles and maps in the world: schema, contacts, clearance, rasterisation, map files.

Every expectation is computed here, independently of `prvo_sim.static_world`: distances by
closed formulas or dense sampling, map cells by hand, polygon interiors by matplotlib's paths.
"""

import math
import re
import warnings

from matplotlib.path import Path
import numpy as np
from PIL import Image
import pytest

from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario
from prvo_sim.world import TeamWorld

HEADER = """\
name: walls
seed: 3
dt: 0.1
duration: 20.0
goal_tolerance: 0.2
"""
ROBOT = """\
robots:
  - name: robot_0
    start: [{x}, {y}]
    goal: [{gx}, {gy}]
    radius: {radius}
    max_speed: {speed}
"""


def scenario_file(tmp_path, shapes, start=(-2.0, 0.0), goal=(2.0, 0.0), radius=0.3, speed=1.0,
                  name='scenario.yaml'):
    path = tmp_path / name
    path.write_text(HEADER + shapes + ROBOT.format(
        x=start[0], y=start[1], gx=goal[0], gy=goal[1], radius=radius, speed=speed))
    return path


def world_of(tmp_path, shapes, **robot):
    return TeamWorld(load_scenario(scenario_file(tmp_path, shapes, **robot)))


def drive(world, velocity, steps):
    positions = [world.positions[0].copy()]
    for _ in range(steps):
        world.step(np.array([velocity], dtype=float))
        positions.append(world.positions[0].copy())
    return np.array(positions)


VERTICAL_WALL = """\
walls:
  - line: [[0.0, -5.0], [0.0, 5.0]]
    thickness: {thickness}
"""


@pytest.mark.parametrize('thickness', [0.0, 0.2])
def test_a_robot_driven_at_a_wall_stops_at_its_surface(tmp_path, thickness):
    world = world_of(tmp_path, VERTICAL_WALL.format(thickness=thickness), start=(-2.0, 0.0))
    path = drive(world, (1.0, 0.0), 40)
    surface = -0.5 * thickness - 0.3
    # Free until the surface, then held there: never past it.
    assert path[:, 0].max() <= surface + 1e-12
    assert path[-1, 0] == pytest.approx(surface, abs=1e-12)
    assert np.allclose(path[:, 1], 0.0)
    assert world.wall_contact_count == 1
    assert world.wall_clearances()[0] == pytest.approx(0.0, abs=1e-12)
    # Ground truth says it stands still there.
    assert np.allclose(world.velocities[0], 0.0, atol=1e-12)


def test_a_fast_robot_does_not_tunnel_through_a_thin_wall(tmp_path):
    # 40 m/s at dt 0.1: 4 m per step, far more than the robot's diameter and the wall's width.
    world = world_of(tmp_path, VERTICAL_WALL.format(thickness=0.0), start=(-1.0, 0.3),
                     speed=40.0)
    path = drive(world, (40.0, 0.0), 5)
    assert (path[:, 0] <= -0.3 + 1e-12).all()
    assert path[-1, 0] == pytest.approx(-0.3, abs=1e-12)


def test_motion_into_a_wall_keeps_its_part_along_the_surface(tmp_path):
    # From (-1, 0) by (1.4, 1.0) in one step: the robot (r 0.3) meets x = -0.3 half-way, at
    # (-0.3, 0.5); the rest (0.7, 0.5) loses its part into the wall, leaving (0, 0.5).
    world = world_of(tmp_path, VERTICAL_WALL.format(thickness=0.0), start=(-1.0, 0.0),
                     speed=20.0)
    world.step(np.array([[14.0, 10.0]]))
    assert world.positions[0] == pytest.approx([-0.3, 1.0], abs=1e-12)
    assert world.velocities[0] == pytest.approx([7.0, 10.0], abs=1e-9)
    assert len(world.last_wall_contacts) == 1
    assert world.last_wall_contacts[0].robot == 0


def _segment_distance(points, a, b):
    """Distances from POINTS (P, 2) to the segment [A, B] by the closed formula."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    points = np.asarray(points, float).reshape(-1, 2)
    t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1)


SHAPES = """\
walls:
  - line: [[-3.0, 2.0], [3.0, 2.5]]
    thickness: 0.3
obstacles:
  - position: [2.0, -2.0]
    radius: 0.5
  - polygon: [[-2.0, -3.0], [-1.0, -3.0], [-1.0, -2.0], [-2.0, -2.0]]
"""


def _analytic_clearance(points):
    """Distances from POINTS (P, 2) to the SHAPES above (negative inside the square)."""
    points = np.asarray(points, float).reshape(-1, 2)
    wall = _segment_distance(points, (-3.0, 2.0), (3.0, 2.5)) - 0.15
    disc = np.linalg.norm(points - (2.0, -2.0), axis=1) - 0.5
    low, high = np.array([-2.0, -3.0]), np.array([-1.0, -2.0])
    outside = np.linalg.norm(np.maximum(np.maximum(low - points, points - high), 0.0), axis=1)
    inside = np.minimum((points - low).min(axis=1), (high - points).min(axis=1))
    square = np.where(outside > 0.0, outside, -inside)
    return np.minimum(np.minimum(wall, disc), square)


def test_clearance_is_the_analytic_distance(tmp_path):
    world = world_of(tmp_path, SHAPES, start=(0.0, 0.0), goal=(0.5, 0.0))
    rng = np.random.default_rng(4)
    points = rng.uniform(-4.0, 4.0, size=(500, 2))
    expected = _analytic_clearance(points)
    assert world.static_world.clearance(points) == pytest.approx(expected, abs=1e-12)
    assert world.wall_clearances()[0] == pytest.approx(_analytic_clearance((0.0, 0.0))[0] - 0.3)


def test_random_motions_never_end_inside_and_free_ones_are_untouched(tmp_path):
    world = world_of(tmp_path, SHAPES, start=(0.0, 0.0), goal=(0.5, 0.0))
    static = world.static_world
    rng = np.random.default_rng(11)
    radius = 0.25
    checked = touched = 0
    while checked < 400:
        start = rng.uniform(-4.0, 4.0, size=2)
        if _analytic_clearance(start)[0] < radius:
            continue
        motion = rng.normal(scale=1.5, size=2)
        end, hit = static.move(start, motion, radius)
        checked += 1
        assert _analytic_clearance(end)[0] >= radius - 1e-9
        # Dense samples of the straight motion: does it ever come within the radius?
        samples = start + np.linspace(0.0, 1.0, 2001)[:, None] * motion
        blocked = _analytic_clearance(samples).min() < radius - 1e-6
        if not hit:
            assert not blocked
            assert np.array_equal(end, start + motion)
        touched += hit
    assert touched > 20


def test_a_robot_against_a_wall_counts_one_contact_and_clearance_reports_it(tmp_path):
    world = world_of(tmp_path, VERTICAL_WALL.format(thickness=0.1), start=(-0.6, 0.0))
    drive(world, (1.0, 0.0), 10)
    drive(world, (-1.0, 0.0), 5)
    drive(world, (1.0, 0.0), 10)
    assert world.wall_contact_count == 2


def _sample_shapes(rng, count):
    """Points of every shape in SHAPES (boundaries included), by this test's own sampler."""
    a, b = np.array([-3.0, 2.0]), np.array([3.0, 2.5])
    along = rng.uniform(0.0, 1.0, count)[:, None]
    angle = rng.uniform(0.0, 2.0 * math.pi, count)
    offset = 0.15 * np.sqrt(rng.uniform(0.0, 1.0, count))
    offset[: count // 4] = 0.15  # on the surface
    wall = a + along * (b - a) + offset[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
    disc_radius = 0.5 * np.sqrt(rng.uniform(0.0, 1.0, count))
    disc_radius[: count // 4] = 0.5
    disc = np.array([2.0, -2.0]) + disc_radius[:, None] * np.stack(
        [np.cos(angle), np.sin(angle)], 1)
    square = rng.uniform([-2.0, -3.0], [-1.0, -2.0], size=(count, 2))
    square[: count // 8, 0] = -1.0  # on an edge, and on a cell boundary of the lattice
    return np.vstack([wall, disc, square])


def test_rasterisation_is_conservative(tmp_path):
    world = world_of(tmp_path, SHAPES, start=(0.0, 0.0), goal=(0.5, 0.0))
    grid = world.static_world.grid
    assert grid.resolution == 0.05
    points = _sample_shapes(np.random.default_rng(5), 20000)
    cells = np.floor((points - grid.origin) / grid.resolution).astype(int)
    assert (cells >= 0).all() and (cells < grid.shape[::-1]).all()
    assert (grid.cells[cells[:, 1], cells[:, 0]] == 100).all()
    # Not everything: a cell whose square keeps 0.1 m from every shape is free.
    centres = grid.origin + grid.resolution * (np.argwhere(grid.cells == 0)[:, ::-1] + 0.5)
    assert len(centres) > 0
    margin = grid.resolution * math.sqrt(0.5)
    assert (_analytic_clearance(centres) > -margin).all()
    occupied = grid.origin + grid.resolution * (np.argwhere(grid.cells == 100)[:, ::-1] + 0.5)
    assert _analytic_clearance(occupied).max() <= margin + 1e-9


def test_a_polygon_rasterises_over_its_interior(tmp_path):
    shapes = """\
obstacles:
  - polygon: [[0.0, 0.0], [3.0, 0.2], [1.4, 0.9], [2.1, 2.7], [0.3, 1.6]]
"""
    world = world_of(tmp_path, shapes, start=(-2.0, 0.0), goal=(-2.0, 1.0))
    grid = world.static_world.grid
    polygon = Path([[0.0, 0.0], [3.0, 0.2], [1.4, 0.9], [2.1, 2.7], [0.3, 1.6]])
    rng = np.random.default_rng(8)
    candidates = rng.uniform([0.0, 0.0], [3.0, 2.7], size=(40000, 2))
    inside = candidates[polygon.contains_points(candidates)]
    assert len(inside) > 10000
    cells = np.floor((inside - grid.origin) / grid.resolution).astype(int)
    assert (grid.cells[cells[:, 1], cells[:, 0]] == 100).all()
    assert world.static_world.clearance(inside).max() <= 0.0


def write_map(tmp_path, levels, text, mode='L', name='map.pgm'):
    Image.fromarray(np.array(levels, dtype=np.uint8), mode=mode).save(tmp_path / name)
    (tmp_path / 'map.yaml').write_text(f'image: {name}\n' + text)
    return 'map.yaml'


# Levels 0 (black) .. 255 (white); the top image row is the grid's last row.
LEVELS = [[0, 100, 200, 255],
          [60, 150, 230, 90]]


@pytest.mark.parametrize('negate, expected', [
    # occupancy p = 1 - level/255 (negate: level/255); > 0.65 -> 100, < 0.25 -> 0, else -1.
    (0, [[100, -1, 0, -1], [100, -1, 0, 0]]),
    (1, [[0, -1, 100, -1], [0, -1, 100, 100]]),
])
def test_a_trinary_map_file_loads_as_map_server_reads_it(tmp_path, negate, expected):
    name = write_map(tmp_path, LEVELS, 'resolution: 0.5\norigin: [-1.0, 2.0, 0.0]\n'
                     f'negate: {negate}\noccupied_thresh: 0.65\nfree_thresh: 0.25\n')
    world = world_of(tmp_path, f'map: {name}\n', start=(20.0, 20.0), goal=(21.0, 20.0))
    grid = world.static_world.map_grid
    # Level/255: top row 0 | .392 | .784 | 1, bottom row .235 | .588 | .902 | .353.
    assert grid.cells.tolist() == expected
    assert grid.resolution == 0.5
    assert grid.origin.tolist() == [-1.0, 2.0]


def test_scale_and_raw_map_files(tmp_path):
    levels = [[0, 140, 255], [40, 100, 250]]
    name = write_map(tmp_path, levels, 'resolution: 0.1\norigin: [0.0, 0.0, 0.0]\nmode: scale\n'
                     'occupied_thresh: 0.65\nfree_thresh: 0.25\nnegate: 0\n')
    world = world_of(tmp_path, f'map: {name}\n', start=(-2.0, 0.0), goal=(-2.0, 1.0))
    # p = 1 - level/255: 40 .843 -> 100; 100 .6078 -> rint(100 (.6078 - .25) / .4) = 89;
    # 250 .0196 -> 0; 0 -> 100; 140 .451 -> rint(50.2) = 50; 255 -> 0.
    assert world.static_world.map_grid.cells.tolist() == [[100, 89, 0], [100, 50, 0]]
    name = write_map(tmp_path, levels, 'resolution: 0.1\norigin: [0.0, 0.0, 0.0]\nmode: raw\n')
    world = world_of(tmp_path, f'map: {name}\n', start=(-2.0, 0.0), goal=(-2.0, 1.0))
    assert world.static_world.map_grid.cells.tolist() == [[40, 100, -1], [0, -1, -1]]


def test_map_cells_are_solid_squares_and_the_grid_keeps_the_map_lattice(tmp_path):
    # One occupied cell [1, 1.5] x [2, 2.5] (bottom row, second column), a wall beside the map.
    name = write_map(tmp_path, [[255, 255, 255], [255, 0, 255]],
                     'resolution: 0.5\norigin: [0.5, 2.0, 0.0]\n')
    shapes = f'map: {name}\nwalls:\n  - line: [[4.0, 0.0], [4.0, 1.0]]\n'
    world = world_of(tmp_path, shapes, start=(-1.0, 2.25), goal=(-1.0, 3.0), speed=20.0)
    assert world.static_world.clearance([[0.5, 2.25], [1.25, 1.5]]).tolist() == pytest.approx(
        [0.5, 0.5])
    world.step(np.array([[20.0, 0.0]]))
    # Stopped with its disc touching the cell's left side x = 1.0.
    assert world.positions[0] == pytest.approx([0.7, 2.25], abs=1e-12)
    grid = world.static_world.grid
    assert grid.resolution == 0.5
    offset = (grid.origin - [0.5, 2.0]) / 0.5
    assert np.allclose(offset, np.round(offset))
    column, row = ((np.array([1.25, 2.25]) - grid.origin) / 0.5).astype(int)
    assert grid.cells[row, column] == 100
    column, row = ((np.array([4.0, 0.5]) - grid.origin) / 0.5).astype(int)
    assert grid.cells[row, column] == 100
    # Cells outside the map file that no shape touches are unknown.
    assert grid.cells[0, 0] == -1


def test_a_scenario_without_shapes_has_no_grid(tmp_path):
    world = world_of(tmp_path, '')
    assert world.static_world.empty and world.static_world.grid is None
    assert world.wall_clearances()[0] == math.inf


@pytest.mark.parametrize('shapes, key, reason', [
    ('walls:\n  - line: [[1.0, 1.0], [1.0, 1.0]]\n', 'walls[0].line', 'the two ends are equal'),
    ('walls:\n  - line: [[1.0, 1.0], [.nan, 1.0]]\n', 'walls[0].line[1][0]',
     'expected a finite number'),
    ('walls:\n  - line: [[1.0, 1.0]]\n', 'walls[0].line', 'expected [[x1, y1], [x2, y2]]'),
    ('walls:\n  - line: [[1.0, 1.0], [2.0, 1.0]]\n    thickness: -0.1\n', 'walls[0].thickness',
     'must be in [0'),
    ('walls:\n  - line: [[1.0, 1.0], [2.0, 1.0]]\n    height: 1\n', 'walls[0].height',
     'unknown key'),
    ('walls: {line: 1}\n', 'walls', 'expected a list'),
    ('obstacles:\n  - position: [1.0, 1.0]\n    radius: 0.0\n', 'obstacles[0].radius',
     'must be in (0'),
    ('obstacles:\n  - position: [1.0, .inf]\n    radius: 0.5\n', 'obstacles[0].position[1]',
     'expected a finite number'),
    ('obstacles:\n  - polygon: [[0.0, 3.0], [1.0, 3.0]]\n', 'obstacles[0].polygon',
     'at least 3 vertices'),
    ('obstacles:\n  - polygon: [[0.0, 3.0], [1.0, 4.0], [1.0, 3.0], [0.0, 4.0]]\n',
     'obstacles[0].polygon', 'edges 0 and 2 cross'),
    ('obstacles:\n  - polygon: [[0.0, 3.0], [2.0, 3.0], [1.0, 3.0]]\n', 'obstacles[0].polygon',
     'its 3 vertices lie on one line: a polygon needs an inside'),
    ('obstacles:\n  - polygon: [[0.0, 3.0], [2.0, 3.0], [1.0, 3.0], [1.0, 4.0]]\n',
     'obstacles[0].polygon', 'edges 0 and 1 overlap'),
    ('obstacles:\n  - polygon: [[0.0, 3.0], [1.0, 3.0], [1.0, 4.0], [0.0, 3.0]]\n',
     'obstacles[0].polygon', 'vertices 3 and 0 are equal: an edge needs a length'),
    # Start (-2, 0), goal (2, 0), radius 0.3.
    ('walls:\n  - line: [[-2.0, -1.0], [-2.0, 1.0]]\n', 'robots[0].start',
     'inside an obstacle'),
    ('obstacles:\n  - position: [2.0, 0.5]\n    radius: 0.3\n', 'robots[0].goal',
     '0.2 m from an obstacle, closer than its radius 0.3 m'),
    ('obstacles:\n  - polygon: [[-3.0, -1.0], [-1.0, -1.0], [-2.0, 1.0]]\n', 'robots[0].start',
     'inside an obstacle'),
    ('map: missing.yaml\n', 'map', 'no map file'),
    ('walls:\n  - line: [[-100000.0, 5.0], [100000.0, 5.0]]\n    thickness: 1.0\n', 'walls',
     'cells of 0.05 m: more than 4e+07'),
])
def test_bad_shapes_are_named(tmp_path, shapes, key, reason):
    path = scenario_file(tmp_path, shapes)
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: {key}: '), message
    assert reason in message, message
    assert '\n' not in message


@pytest.mark.parametrize('block', ['scripted', 'upstream', 'path'])
def test_a_last_waypoint_inside_a_wall_is_named_by_its_key(tmp_path, block):
    # No goal key: the robot's goal is its last waypoint, (2, 0), on the wall.
    path = tmp_path / 'scenario.yaml'
    path.write_text(HEADER + 'walls:\n  - line: [[2.0, -1.0], [2.0, 1.0]]\nrobots:\n'
                    '  - name: robot_0\n    start: [-2.0, 0.0]\n    radius: 0.3\n'
                    f'    max_speed: 1.0\n    {block}:\n'
                    '      waypoints: [[-2.0, 2.0], [0.0, 2.0], [2.0, 0.0]]\n')
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: robots[0].{block}.waypoints[2]: '), message
    assert 'inside an obstacle' in message, message


MAP = 'image: map.pgm\nresolution: 0.5\norigin: [0.0, 5.0, 0.0]\n'


@pytest.mark.parametrize('text, key, reason', [
    (MAP.replace('0.5', '0.0'), 'resolution', 'must be in (0'),
    (MAP.replace('0.5', '-1.0'), 'resolution', 'must be in (0'),
    (MAP + 'occupied_thresh: 1.5\n', 'occupied_thresh', 'must be in [0, 1]'),
    (MAP + 'free_thresh: -0.1\n', 'free_thresh', 'must be in [0, 1]'),
    (MAP + 'free_thresh: 0.7\n', 'free_thresh', 'above occupied_thresh'),
    (MAP + 'mode: fancy\n', 'mode', 'must be one of trinary, scale, raw'),
    (MAP + 'negate: 2\n', 'negate', 'expected 0 or 1'),
    (MAP.replace('map.pgm', 'nothing.pgm'), 'image', 'cannot read'),
    (MAP.replace('map.pgm', 'map.yaml'), 'image', 'cannot read'),
    (MAP.replace(', 0.0]', ', 0.5]'), 'origin[2]', 'yaw 0'),
    (MAP.replace('[0.0, 5.0', '[.nan, 5.0'), 'origin[0]', 'expected a finite number'),
    (MAP.replace('resolution: 0.5\n', ''), 'resolution', 'missing required key'),
    (MAP + 'colour: red\n', 'colour', 'unknown key'),
])
def test_bad_map_files_are_named(tmp_path, text, key, reason):
    Image.fromarray(np.full((2, 2), 255, dtype=np.uint8)).save(tmp_path / 'map.pgm')
    (tmp_path / 'map.yaml').write_text(text)
    path = scenario_file(tmp_path, 'map: map.yaml\n')
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{tmp_path / "map.yaml"}: {key}: '), message
    assert reason in message, message


def test_an_unreadable_image_is_named(tmp_path):
    (tmp_path / 'map.pgm').write_bytes(b'P5 not really')
    (tmp_path / 'map.yaml').write_text(MAP)
    with pytest.raises(ScenarioError, match=re.escape(f'{tmp_path / "map.yaml"}: image: ')):
        load_scenario(scenario_file(tmp_path, 'map: map.yaml\n'))


@pytest.mark.parametrize('width, height', [
    # Above the 4e7-cell bound, above Pillow's warning limit (8.9e7), above its error limit.
    (7000, 6000), (10000, 10000), (60000, 60000)])
def test_an_image_declaring_too_many_pixels_is_refused_before_decoding(tmp_path, width, height):
    # A header alone: decoding it would read pixels that are not there.
    (tmp_path / 'map.pgm').write_bytes(f'P5\n{width} {height}\n255\n'.encode())
    (tmp_path / 'map.yaml').write_text(MAP)
    with warnings.catch_warnings(), pytest.raises(ScenarioError) as raised:
        # A warning would be a second line on the terminal.
        warnings.simplefilter('error')
        load_scenario(scenario_file(tmp_path, 'map: map.yaml\n'))
    message = str(raised.value)
    assert message.startswith(f'{tmp_path / "map.yaml"}: image: '), message
    assert 'more than 4e+07 pixels' in message, message
    assert str(width * height) in message or f'{width} x {height}' in message, message
    assert '\n' not in message


def test_a_robot_in_a_map_cell_is_refused(tmp_path):
    write_map(tmp_path, [[0, 0], [0, 0]], 'resolution: 1.0\norigin: [-3.0, -1.0, 0.0]\n')
    with pytest.raises(ScenarioError, match=re.escape('robots[0].start: [-2.0, 0.0] is inside')):
        load_scenario(scenario_file(tmp_path, 'map: map.yaml\n'))


@pytest.mark.parametrize('name', ['corridor8', 'doorway8', 'pillars12', 'office', 'u_trap'])
def test_shipped_wall_scenarios_have_their_shapes(name):
    scenario = load_scenario(find_scenario(name))
    static = scenario.static_world
    assert not static.empty
    starts = np.array([robot.start for robot in scenario.robots])
    radii = np.array([robot.radius for robot in scenario.robots])
    assert (static.clearance(starts) >= radii).all()
    assert (static.grid.cells == 100).any()


def test_the_corridor_is_2_4_m_wide_and_12_m_long():
    static = load_scenario(find_scenario('corridor8')).static_world
    # Clearances from the corridor's centre line and its middle measured by formulas.
    assert static.clearance([[0.0, 0.0]])[0] == pytest.approx(1.2)
    assert static.clearance([[0.0, 0.0], [5.9, 0.0]]).tolist() == pytest.approx([1.2, 0.1])


def test_wall_metrics_from_recorded_positions(tmp_path):
    from prvo_sim import metrics

    world = world_of(tmp_path, VERTICAL_WALL.format(thickness=0.2), start=(-2.0, 0.0))
    # robot a walks to the wall's surface (x = -0.1 - 0.3), leaves, comes back: two contacts;
    # robot b stays 1 m clear.
    a = np.array([[-2.0, 0.0], [-0.4, 0.0], [-0.4, 1.0], [-1.0, 1.0], [-0.4, 1.0]])
    b = np.column_stack([np.full(5, 1.4), np.linspace(-1.0, 1.0, 5)])
    positions = np.stack([a, b], axis=1)
    result = metrics.wall_metrics(positions, [0.3, 0.3], ['a', 'b'],
                                  world.static_world.clearance)
    assert result['robots']['a'] == {'wall_contacts': 2,
                                     'min_wall_clearance': pytest.approx(0.0, abs=1e-12)}
    assert result['robots']['b'] == {'wall_contacts': 0,
                                     'min_wall_clearance': pytest.approx(1.4 - 0.1 - 0.3)}
    assert result['wall_contacts'] == 2
    assert result['min_wall_clearance'] == pytest.approx(0.0, abs=1e-12)
    empty = metrics.wall_metrics(positions, [0.3, 0.3], ['a', 'b'])
    assert empty['wall_contacts'] == 0 and empty['min_wall_clearance'] is None
