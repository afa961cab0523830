"""Runs in a world with walls: metrics.json's wall fields and the bag's /map, by both engines."""

import json
import pathlib

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from prvo_sim import run_scenario
from prvo_sim.scenario import find_scenario, load_scenario

# u_trap for a few seconds: the robot inside the U drives into its closed side (its planner,
# listening for a map elsewhere, has none).
SHORT = 4.0


def short_u_trap(tmp_path):
    text = find_scenario('u_trap').read_text().replace(
        'duration: 60.0', f'duration: {SHORT}').replace(
        '  eta: 0.8\n', '  eta: 0.8\n  map_topic: /unheard\n')
    path = tmp_path / 'u_trap_short.yaml'
    path.write_text(text)
    return path


def read_bag(folder):
    messages = {}
    with AnyReader([pathlib.Path(folder)]) as reader:
        for connection, timestamp, data in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (timestamp, reader.deserialize(data, connection.msgtype)))
    return messages


def test_inprocess_run_reports_wall_clearance_and_records_the_map(tmp_path):
    path = short_u_trap(tmp_path)
    out = tmp_path / 'out'
    assert run_scenario.main([str(path), '--engine', 'inprocess', '--out', str(out),
                              '--quiet', '--no-animation']) == 0
    recorded = json.loads((out / 'metrics.json').read_text())
    robot = recorded['robots']['robot_0']
    # Independent: the robot (r 0.25) inside walls at x = 1.5 and y = +-1.5 (0.1 thick) keeps
    # its centre at most 1.5 - 0.05 - 0.25 = 1.2 from the origin along x.
    trajectory = np.genfromtxt(out / 'trajectories.csv', delimiter=',', names=True,
                               dtype=None, encoding=None)
    x, y = trajectory['x'], trajectory['y']
    assert x.max() <= 1.2 + 1e-9
    clearance = np.minimum.reduce([1.5 - 0.05 - x, 1.5 - 0.05 - y, y + 1.5 - 0.05]) - 0.25
    assert robot['min_wall_clearance'] == pytest.approx(clearance.min(), abs=1e-9)
    assert recorded['min_wall_clearance'] == robot['min_wall_clearance']
    assert recorded['wall_contacts'] == robot['wall_contacts'] >= 1
    touching = clearance <= 1e-9
    assert robot['wall_contacts'] == int((touching & ~np.r_[False, touching[:-1]]).sum())
    (_, grid), = read_bag(out / 'bag')['/map']
    expected = load_scenario(path).static_world.grid
    assert grid.header.frame_id == 'map'
    assert np.array_equal(np.asarray(grid.data, dtype=np.int8).reshape(expected.shape),
                          expected.cells)


def test_a_run_without_walls_has_no_map_and_no_wall_contacts(tmp_path):
    out = tmp_path / 'out'
    assert run_scenario.main(['headon2', '--engine', 'inprocess', '--out', str(out), '--quiet',
                              '--no-animation']) == 0
    recorded = json.loads((out / 'metrics.json').read_text())
    assert (recorded['wall_contacts'], recorded['min_wall_clearance']) == (0, None)
    assert '/map' not in read_bag(out / 'bag')
