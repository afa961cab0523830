"""Planners with the simulator's map on both engines: the same way out of a U, to the bit."""

import csv
import json
import pathlib

from runner_testing import output, start_runner

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def rows_of(path):
    """Return {(time, robot): [x, y, vx, vy]} of a trajectories.csv."""
    with open(path) as csv_file:
        return {(row['time'], row['robot']): [float(row[key]) for key in ('x', 'y', 'vx', 'vy')]
                for row in csv.DictReader(csv_file)}


def test_both_engines_route_the_robot_out_of_the_u_alike(tmp_path, runners):
    # u_trap for 4 s: with the map the robot heads out of the U's open side, away from its goal.
    path = tmp_path / 'u_trap.yaml'
    path.write_text((SCENARIOS / 'u_trap.yaml').read_text().replace(
        'duration: 60.0', 'duration: 4.0'))
    outs = {}
    for engine in ('inprocess', 'ros'):
        outs[engine] = tmp_path / engine
        runner = start_runner([str(path), '--engine', engine, '--out', str(outs[engine]),
                               '--quiet', '--no-animation', '--no-bag'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=600) == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv') for engine in outs)
    assert inprocess and set(inprocess) <= set(ros)
    for key, values in inprocess.items():
        assert max(abs(value - other) for value, other in zip(values, ros[key],
                                                               strict=True)) <= 1e-9, key
    # Out by the open side (x < 0): the goal lies at x = 4 m beyond the closed one.
    assert min(x for x, _, _, _ in inprocess.values()) < -1.0
    metrics = {engine: json.loads((outs[engine] / 'metrics.json').read_text())
               for engine in outs}
    assert metrics['ros']['wall_contacts'] == metrics['inprocess']['wall_contacts'] == 0
