"""A world with walls on both engines: the same trajectories, wall metrics and /map in the bag."""

import csv
import json
import pathlib

from rosbags.highlevel import AnyReader
from runner_testing import output, start_runner

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def rows_of(path):
    """Return {(time, robot): [x, y, vx, vy]} of a trajectories.csv."""
    with open(path) as csv_file:
        return {(row['time'], row['robot']): [float(row[key]) for key in ('x', 'y', 'vx', 'vy')]
                for row in csv.DictReader(csv_file)}


def map_messages(folder):
    """Return [(log time, frame, resolution, origin, (height, width), cells)] of /map in FOLDER.

    Decoded: the middleware leaves the alignment padding of a serialized message undefined.
    """
    with AnyReader([pathlib.Path(folder)]) as reader:
        connections = [connection for connection in reader.connections
                       if connection.topic == '/map']
        messages = []
        for connection, timestamp, data in reader.messages(connections=connections):
            grid = reader.deserialize(data, connection.msgtype)
            info = grid.info
            messages.append((timestamp, grid.header.frame_id, info.resolution,
                             (info.origin.position.x, info.origin.position.y),
                             (info.height, info.width), grid.data.tolist()))
        return messages


def test_both_engines_stop_the_robot_at_the_same_wall(tmp_path, runners):
    # u_trap for 4 s: the robot drives into the closed side of the U and is held there (its
    # planner, listening for a map elsewhere, has none).
    path = tmp_path / 'u_trap.yaml'
    path.write_text((SCENARIOS / 'u_trap.yaml').read_text().replace(
        'duration: 60.0', 'duration: 4.0').replace(
        '  eta: 0.8\n', '  eta: 0.8\n  map_topic: /unheard\n'))
    outs = {}
    for engine in ('inprocess', 'ros'):
        outs[engine] = tmp_path / engine
        runner = start_runner([str(path), '--engine', engine, '--out', str(outs[engine]),
                               '--quiet', '--no-animation'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=600) == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv') for engine in outs)
    # A run that ends at its duration: the ROS run records the final state too.
    assert inprocess and set(inprocess) <= set(ros)
    for key, values in inprocess.items():
        assert max(abs(value - other) for value, other in zip(values, ros[key],
                                                               strict=True)) <= 1e-9, key
    metrics = {engine: json.loads((outs[engine] / 'metrics.json').read_text())
               for engine in outs}
    assert metrics['ros']['wall_contacts'] == metrics['inprocess']['wall_contacts'] >= 1
    assert metrics['ros']['min_wall_clearance'] == metrics['inprocess']['min_wall_clearance']
    maps = {engine: map_messages(outs[engine] / 'bag') for engine in outs}
    assert len(maps['ros']) == 1 and maps['ros'] == maps['inprocess']
