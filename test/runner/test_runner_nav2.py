"""Robots driven by the Nav2 stand-in: both engines give the same trajectories."""

import pathlib

from runner_testing import output, start_runner
from test_runner_engines import rows_of

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def test_both_engines_drive_the_stand_in_team_alike(tmp_path, runners):
    outs = {}
    for engine in ('inprocess', 'ros'):
        outs[engine] = tmp_path / engine
        runner = start_runner([str(SCENARIOS / 'nav2_headon2.yaml'), '--engine', engine,
                               '--out', str(outs[engine]), '--quiet', '--no-bag',
                               '--no-animation'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=900) == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv') for engine in outs)
    assert inprocess and set(inprocess) == set(ros)
    for key, values in inprocess.items():
        pairs = [(value, other) for value, other in zip(values, ros[key], strict=True)
                 if value is not None and other is not None]
        assert max(abs(value - other) for value, other in pairs) <= 1e-9, (key, values, ros[key])
