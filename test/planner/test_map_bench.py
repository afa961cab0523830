"""The map benchmark runs and reports every figure (no timing is asserted)."""

import json

from prvo_planner import map_bench
from prvo_sim.scenario import MAP_BYTES_PER_CELL


def test_the_map_benchmark_writes_a_row_per_map(tmp_path, capsys):
    output = tmp_path / 'rows.json'
    assert map_bench.main(['--sizes', '8', '12', '--resolution', '0.1',
                           '--json', str(output)]) == 0
    rows = json.loads(output.read_text())
    assert [row['size_m'] for row in rows] == [8.0, 12.0]
    assert all(row['segments'] > 0 and row['cells'] == (row['size_m'] * 10) ** 2
               for row in rows)
    assert all(0.0 < row['kept_bytes_per_cell'] < row['peak_bytes_per_cell'] for row in rows)
    assert '| 8 m at 0.1 m |' in capsys.readouterr().out


def test_a_map_of_a_million_cells_is_built_within_the_runners_estimate_per_cell():
    """Issue 36 item 2: a planner's map costs a small constant per cell (it was 280 bytes)."""
    row = map_bench.build_memory(map_bench.office(50.0, 0.05))
    assert row['peak_bytes_per_cell'] <= MAP_BYTES_PER_CELL
    # What a planner keeps: the grid's flags, the steps allowed, the margin's costs, a tree, the
    # passages' cells.
    assert row['kept_bytes_per_cell'] <= 20.0


def test_the_callback_table_times_a_node_that_takes_each_map(tmp_path, capsys, monkeypatch,
                                                             ros_domain):
    monkeypatch.setenv('ROS_DOMAIN_ID', str(ros_domain))
    output = tmp_path / 'rows.json'
    assert map_bench.main(['--sizes', '8', '--resolution', '0.1', '--callbacks',
                           '--json', str(output)]) == 0
    row, = json.loads(output.read_text())
    # The map was in force only after the callback had returned.
    assert 0.0 < row['callback_ms'] <= row['in_force_after_ms']
    assert row['callback_building_ms'] > 0.0
    assert '| map callback [ms] |' in capsys.readouterr().out
