"""The profile of default plans runs and reports its tables (no timing is asserted)."""

import json

from prvo_planner import bench


def test_the_profile_reports_every_case_and_the_certificate(tmp_path, capsys):
    output = tmp_path / 'profile.json'
    assert bench.main(['--profile', '--repeats', '2', '--top', '3', '--clock', 'cpu',
                       '--json', str(output)]) == 0
    rows = json.loads(output.read_text())['results']
    assert [(row['neighbours'], row['walls']) for row in rows] == [
        (count, walls) for count in bench.PROFILE_NEIGHBOURS for walls in (0, bench.WALL_COUNT)]
    for row in rows:
        # Every plan goes through the planner, and the certified bound certifies some neighbour.
        assert row['functions']['planner.plan_velocity']['calls'] == 1.0
        assert row['functions']['certificate.condition_bound']['calls'] >= 1.0
        assert 0 < row['numpy_calls'] < row['calls']
        assert 0.0 < row['core_self_ms'] <= row['profiled_ms']
        # The kernels counted as compiled are the core's numba dispatchers, the ray search's
        # among them, and not its Python glue.
        functions = row['functions']
        assert row['compiled_ms'] >= functions['ray_search.team_gaps']['self_ms'] > 0.0
        assert row['compiled_ms'] + functions['planner._certified_choice']['self_ms'] <= (
            row['core_self_ms'] + 1e-9)
    out = capsys.readouterr().out
    assert '| 20 | 50 |' in out and 'compiled kernels ms' in out
    assert 'self ms per plan' in out and 'cumulative ms per plan' in out


def test_the_profile_plans_with_the_node_defaults():
    config = bench.profile_config()
    assert (config.certificate, config.eta, config.num_directions) == ('certified', 0.95, 64)
