"""The doorway sweep: its worlds, its door measures on a hand-made run, a small run, bad input."""

import json

import numpy as np
import pytest

from prvo_sim.bench import doorway_sweep as sweep
from prvo_sim.scenario import find_scenario, load_scenario


@pytest.mark.parametrize('count', [1, 2, 4, 8, 12])
def test_each_count_is_a_valid_world_in_which_every_robot_must_cross_the_door(tmp_path, count):
    # Through the loader: it refuses robots overlapping each other or a wall at the start.
    scenario = load_scenario(sweep.write_doorway(tmp_path, count))
    starts = np.array([robot.start for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    radii = np.array([robot.radius for robot in scenario.robots])
    assert len(starts) == 2 * count
    assert np.all(starts[:count, 0] < 0.0) and np.all(starts[count:, 0] > 0.0)
    assert np.all(np.sign(goals[:, 0]) == -np.sign(starts[:, 0]))
    # Each straight line meets x = 0 inside the door with a radius to spare from the jambs.
    fraction = starts[:, 0] / (starts[:, 0] - goals[:, 0])
    crossing = starts[:, 1] + fraction * (goals[:, 1] - starts[:, 1])
    assert np.all(np.abs(crossing) <= 0.5 * sweep.DOOR_WIDTH - radii)
    gaps = np.linalg.norm(starts[:, None] - starts[None], axis=2) - radii[:, None] - radii
    assert np.all(gaps[~np.eye(len(starts), dtype=bool)] > 0.0)
    world = scenario.static_world
    assert np.all(world.clearance(starts) > radii) and np.all(world.clearance(goals) > radii)
    # The door: 1.2 m clear between the jambs' rounded tips, the only way through the wall.
    jambs = [(line, thickness) for line, thickness in world.walls if np.all(line[:, 0] == 0.0)]
    assert len(jambs) == 2
    tips = sorted(float(np.min(np.abs(line[:, 1])) - 0.5 * thickness) for line, thickness in jambs)
    assert tips == pytest.approx([0.5 * sweep.DOOR_WIDTH] * 2)
    assert scenario.duration == sweep.DURATION_BASE + sweep.DURATION_PER_PAIR * count
    assert sweep.grid_shape(count) == {1: (1, 1), 2: (2, 1), 4: (2, 2), 8: (4, 2),
                                       12: (4, 3)}[count]


def test_four_each_way_is_the_shipped_doorway8(tmp_path):
    built = load_scenario(sweep.write_doorway(tmp_path, 4))
    shipped = load_scenario(find_scenario('doorway8'))
    for ours, theirs in zip(built.robots, shipped.robots, strict=True):
        np.testing.assert_array_equal(ours.start, theirs.start)
        np.testing.assert_array_equal(ours.goal, theirs.goal)
        assert (ours.radius, ours.max_speed, ours.noise) == (theirs.radius, theirs.max_speed,
                                                             theirs.noise)
    for (ours, thickness), (theirs, shipped_thickness) in zip(
            built.static_world.walls, shipped.static_world.walls, strict=True):
        np.testing.assert_allclose(ours, theirs)
        assert thickness == shipped_thickness
    assert (built.duration, built.seed) == (shipped.duration, shipped.seed)


def hand_made_run():
    """Return times (41,), positions (41, 3, 2), radii (3,), goals (3, 2): 4 s at 0.1 s.

    a drives left to right along y = 0 at 1 m/s; b waits, then drives right to left from
    1.5 s; c (left to right, y = 0.3) enters the door, backs out, enters again and stays.
    """
    times = np.linspace(0.0, 4.0, 41)
    xs = [np.interp(times, [0.0, 2.0], [-1.0, 1.0]),
          np.interp(times, [0.0, 1.5, 3.5], [1.0, 1.0, -1.0]),
          np.interp(times, [0.0, 1.0, 2.0, 3.0], [-1.0, 0.0, -1.0, 0.0])]
    ys = [0.0, 0.0, 0.3]
    positions = np.stack([np.column_stack([x, np.full_like(x, y)]) for x, y in zip(
        xs, ys, strict=True)], axis=1)
    return times, positions, np.full(3, 0.2), np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, -0.3]])


def test_door_measures_of_a_hand_made_run():
    times, positions, radii, goals = hand_made_run()
    # Through once the centre is 0.05 + 0.2 m past x = 0: a at x = 0.3 (1.3 s), b at x = -0.3
    # (2.8 s); c never.
    through = sweep.through_times(times, positions, radii, goals)
    np.testing.assert_allclose(through[:2], [1.3, 2.8])
    assert np.isnan(through[2])
    # Not all through: T is the run's length.
    assert sweep.throughput(through, times[-1]) == pytest.approx(60.0 * 2 / 4.0)
    # All through: T is the last one's time through.
    assert sweep.throughput(through[:2], times[-1]) == pytest.approx(60.0 * 2 / 2.8)
    assert sweep.throughput(np.full(2, np.nan), times[-1]) is None
    # In the doorway while |x| < 0.25: from the first sample in to the next one out.
    intervals = sweep.doorway_intervals(times, positions, radii)
    expected = [[(0.8, 1.3)], [(2.3, 2.8)], [(0.8, 1.3), (2.8, 4.0)]]
    for got, want in zip(intervals, expected, strict=True):
        np.testing.assert_allclose(got, want)
    # Beside the door (|y| >= 0.6) is not in it.
    beside = positions.copy()
    beside[:, 0, 1] = 0.7
    assert sweep.doorway_intervals(times, beside, radii)[0] == []
    np.testing.assert_array_equal(sweep.way_signs(goals), [1, -1, 1])


def test_one_each_way_gets_both_through_and_draws_the_turns(tmp_path, capsys):
    output, figure = tmp_path / 'sweep.json', tmp_path / 'turns.png'
    code = sweep.main(['--counts', '1', '--seeds', '1', '--peers', '--json', str(output),
                       '--figure', str(figure)])
    rows = json.loads(output.read_text())['runs']
    assert code == 0 and len(rows) == 1
    row = rows[0]
    assert (row['each_way'], row['planner'], row['noise'], row['seeds']) == (1, 'prvo', '0.05',
                                                                             '7')
    assert row['through'] == '2/2' and row['arrivals'] == '2/2'
    assert row['contacts'] == 0 and row['wall_contacts'] == 0
    # Both through before the makespan, which is at most the 45 s the world allows.
    assert 60.0 * 2 / row['makespan_s'] <= row['throughput_per_min']
    assert '| 1 | prvo | 0.05 | 7 | 2/2 | 2/2 |' in capsys.readouterr().out
    assert figure.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize(('arguments', 'option'), [
    (['--counts', '0'], '--counts'), (['--counts', '2', '-1'], '--counts'),
    (['--counts', str(sweep.MAX_COUNT + 1)], '--counts'), (['--seeds', '0'], '--seeds'),
    (['--counts', '1', '--figure-count', '2'], '--figure-count'),
    (['--planner', 'right_of_way=maybe'], '--planner')])
def test_bad_input_is_one_line_naming_the_option_and_exit_2(arguments, option, capsys):
    assert sweep.main(arguments) == 2
    errors = capsys.readouterr().err.splitlines()
    assert len(errors) == 1
    assert errors[0].startswith(f'prvo_sim.bench.doorway_sweep: error: {option}: '), errors
