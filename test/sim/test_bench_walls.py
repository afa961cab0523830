"""The wall benchmark: the peers' shapes, its measures and its command line, without peers."""

import json
import math
import sys

import numpy as np
import pytest
import yaml

from prvo_sim.bench import walls as bench_walls
from prvo_sim.bench.walls import (
    counter_clockwise,
    disc_polygon,
    peer_world,
    trajectory_row,
    wall_rectangle,
)
from prvo_sim.scenario import load_scenario


def convex_ccw_contains(vertices, points, slack=1e-12):
    """Return whether every point lies inside or on the convex polygon VERTICES.

    Also asserts the polygon turns left at every vertex (convex, counter-clockwise).
    """
    edges = np.roll(vertices, -1, axis=0) - vertices
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(
        edges, -1, axis=0)[:, 0]
    assert np.all(turns > 0.0)
    offsets = points[:, None, :] - vertices[None]
    sides = edges[None, :, 0] * offsets[..., 1] - edges[None, :, 1] * offsets[..., 0]
    return bool(np.all(sides >= -slack))


def capsule_boundary(start, end, half, count=200):
    """Return COUNT points on the capsule boundary of half-width HALF around [START, END]."""
    along = (end - start) / np.linalg.norm(end - start)
    normal = np.array([-along[1], along[0]])
    fractions = np.linspace(0.0, 1.0, count)[:, None]
    sides = [start + fractions * (end - start) + sign * half * normal for sign in (1, -1)]
    angles = np.linspace(-0.5 * math.pi, 0.5 * math.pi, count)[:, None]
    caps = [centre + half * (sign * np.cos(angles) * along + np.sin(angles) * normal)
            for centre, sign in ((end, 1), (start, -1))]
    return np.vstack(sides + caps)


def test_a_wall_and_a_disc_become_counter_clockwise_polygons_around_them():
    rng = np.random.default_rng(23)
    for _ in range(20):
        start, end = rng.uniform(-5.0, 5.0, size=(2, 2))
        thickness = rng.uniform(0.0, 0.3)
        rectangle = wall_rectangle([start, end], thickness)
        assert convex_ccw_contains(rectangle, capsule_boundary(start, end, 0.5 * thickness))
        # No larger than needed: its corners lie within sqrt(2) half-widths of the ends.
        half = 0.5 * max(thickness, bench_walls.THIN_WALL_WIDTH)
        assert min(np.linalg.norm(rectangle - point, axis=1).max() for point in (start, end)) \
            <= math.hypot(np.linalg.norm(end - start) + half, half) + 1e-9
    # A wall without thickness is still a polygon with an inside: RVO2 tests both sides.
    thin = wall_rectangle([[0.0, 0.0], [2.0, 0.0]], 0.0)
    assert np.ptp(thin[:, 1]) == pytest.approx(bench_walls.THIN_WALL_WIDTH)
    centre, radius = np.array([1.0, -2.0]), 0.4
    polygon = disc_polygon(centre, radius)
    angles = np.linspace(0.0, 2.0 * math.pi, 500)
    circle = centre + radius * np.column_stack([np.cos(angles), np.sin(angles)])
    assert convex_ccw_contains(polygon, circle, slack=1e-9)
    # Circumscribed: every edge's midpoint lies on the circle.
    midpoints = 0.5 * (polygon + np.roll(polygon, -1, axis=0))
    np.testing.assert_allclose(np.linalg.norm(midpoints - centre, axis=1), radius)


def test_a_clockwise_polygon_is_reversed_a_counter_clockwise_one_kept():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    np.testing.assert_array_equal(counter_clockwise(square), square)
    np.testing.assert_array_equal(counter_clockwise(square[::-1]), square)


def write(tmp_path, document):
    """Write DOCUMENT as a scenario file in TMP_PATH and return its path."""
    path = tmp_path / f'{document["name"]}.yaml'
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def one_wall_document(name='one_wall', duration=6.0):
    """Return a scenario of two robots below a 0.2 m thick wall along y = 1, x in [-1, 1]."""
    return {
        'name': name, 'seed': 3, 'dt': 0.1, 'duration': duration, 'goal_tolerance': 0.2,
        'noise': {'position_std': 0.01, 'velocity_std': 0.01, 'actuation_std': 0.01},
        'walls': [{'line': [[-1.0, 1.0], [1.0, 1.0]], 'thickness': 0.2}],
        'obstacles': [{'position': [4.0, 4.0], 'radius': 0.5},
                      {'polygon': [[6.0, 0.0], [6.0, 1.0], [7.0, 1.0]]}],
        'robots': [{'name': 'a', 'start': [-1.0, 0.5], 'goal': [1.0, 0.5], 'radius': 0.25,
                    'max_speed': 1.0},
                   {'name': 'b', 'start': [0.0, -1.0], 'goal': [0.0, -1.0], 'radius': 0.3,
                    'max_speed': 1.0}]}


def test_a_hand_made_trajectory_is_measured_against_the_walls_and_the_robots(tmp_path):
    scenario = load_scenario(write(tmp_path, one_wall_document()))
    # Robot a drives along y = 0.5 at 1 m/s, 0.4 m below the wall's face (0.15 m clearance),
    # except at t = 1 s, when it is at y = 0.65 (touching); b stands, except at t = 0.5 s when
    # it is at (-0.5, 0.0): centres 0.5 m apart, 0.55 m of radii.
    times = np.arange(21) * 0.1
    a = np.column_stack([-1.0 + times, np.where(np.isclose(times, 1.0), 0.65, 0.5)])
    b = np.tile([0.0, -1.0], (21, 1))
    b[5] = [-0.5, 0.0]
    row = trajectory_row(scenario, times, np.stack([a, b], axis=1), np.array([1.0, 3.0]))
    assert row['robots'] == 2 and row['arrived'] == 2
    # a is within 0.2 m of its goal from x = 0.8 m, t = 1.8 s (b is there from the start).
    assert row['makespan_s'] == pytest.approx(1.8)
    assert row['min_separation_m'] == pytest.approx(-0.05) and row['contacts'] == 1
    assert row['min_wall_clearance_m'] == pytest.approx(0.0, abs=1e-12)
    assert row['wall_contacts'] == 1
    assert row['plan_ms_per_robot_step'] == 2.0
    # Nobody stalls; a drives through, near one spot for half a metre at the most (0.5 s).
    assert (row['stalls'], row['longest_stall_s']) == (0, 0.0)
    assert 0.0 < row['longest_dwell_s'] <= 0.5


def test_the_peers_are_given_the_walls_and_obstacles_of_the_scenario(tmp_path):
    world = peer_world(load_scenario(write(tmp_path, one_wall_document())))
    assert len(world.polygons) == 2
    # The clockwise triangle comes out counter-clockwise.
    assert convex_ccw_contains(world.polygons[1], np.array([[6.2, 0.5]]))
    np.testing.assert_array_equal(world.disc_centres, [[4.0, 4.0]])
    np.testing.assert_array_equal(world.goals, [[1.0, 0.5], [0.0, -1.0]])
    np.testing.assert_array_equal(world.radii, [0.25, 0.3])


def test_without_peers_the_command_skips_each_in_one_line_and_runs_prvo(tmp_path, monkeypatch,
                                                                        capsys):
    for package in ('pyrvo', 'navground'):
        # A None entry makes the import fail: the peer is absent.
        monkeypatch.setitem(sys.modules, package, None)
    path = write(tmp_path, one_wall_document('short', duration=4.0))
    output = tmp_path / 'out' / 'bench.json'
    code = bench_walls.main(['--scenarios', str(path), '--methods', 'prvo', '--json',
                             str(output)])
    printed = capsys.readouterr().out
    for peer, package in bench_walls.PEER_PACKAGES.items():
        assert printed.count(f'{peer}: {package} is not importable here, skipped') == 2
    result = json.loads(output.read_text())
    assert [(row['planner'], row['noise']) for row in result['runs']] == [
        ('prvo --method prvo', 'none'), ('prvo --method prvo', '0.01')]
    assert all(row['arrivals'] == '2/2' for row in result['runs'])
    assert all(row['stalls'] == 0 and row['longest_stall_s'] == 0.0 and row['longest_dwell_s'] >= 0
               for row in result['runs'])
    assert len(result['notes']) == 3 and code == 0


def test_bad_input_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    assert bench_walls.main(['--seeds', '0']) == 2
    assert bench_walls.main(['--scenarios', str(tmp_path / 'missing.yaml')]) == 2
    # A map is not given to the peers: refused before anything runs.
    monkeypatch.setattr(bench_walls, 'importable_peers', lambda peers, notes: list(peers))
    assert bench_walls.main(['--scenarios', 'office', '--peers', 'rvo2-orca']) == 2
    errors = capsys.readouterr().err.splitlines()
    prefix = 'prvo_sim.bench.walls: error: '
    assert len(errors) == 3 and all(line.startswith(prefix) for line in errors)
    assert 'map file' in errors[2]
    for item, reason in (('keep_right=2', 'keep_right: must be in [0.0, 0.8], got 2.0'),
                         ('no_such=1', 'no_such: unknown planner parameter'),
                         ('keep_right', "'keep_right' is not NAME=VALUE")):
        assert bench_walls.main(['--scenarios', 'corridor8', '--planner', item]) == 2
        error = capsys.readouterr().err.strip()
        assert error.startswith(prefix + '--planner: ' + reason), error


def test_planner_parameters_given_reach_every_robot_over_the_scenario_s(tmp_path):
    scenario = load_scenario(write(tmp_path, one_wall_document()))
    overrides = bench_walls.planner_overrides(['keep_right=0', 'certificate=cantelli'])
    assert overrides == {'keep_right': 0.0, 'certificate': 'cantelli'}
    chosen = bench_walls.with_planner(scenario, overrides)
    for robot, before in zip(chosen.robots, scenario.robots, strict=True):
        assert robot.planner == {**before.planner, **overrides}
    assert bench_walls.with_planner(scenario, {}) is scenario


def test_rvo2_keeps_a_robot_off_a_wall_of_no_thickness(tmp_path):
    pytest.importorskip('pyrvo')
    document = one_wall_document('thin')
    document['walls'] = [{'line': [[0.0, -2.0], [0.0, 2.0]]}]
    document['obstacles'] = []
    document['robots'] = [{'name': 'a', 'start': [-1.0, 0.0], 'goal': [1.0, 0.0],
                           'radius': 0.25, 'max_speed': 1.0}]
    scenario = load_scenario(write(tmp_path, document))
    row = trajectory_row(scenario, *bench_walls.peer_trajectory('rvo2-orca',
                                                                peer_world(scenario)))
    assert row['arrived'] == 0 and row['min_wall_clearance_m'] > -1e-3
