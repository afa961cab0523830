"""Doorway sweep: N robots each way through one door, prvo beside RVO2 (issue 39).

    python -m prvo_sim.bench.doorway_sweep [--counts 1 2 4 8 12] [--seeds 3]
                                           [--planner NAME=VALUE ...] [--peers rvo2-orca ...]
                                           [--json PATH] [--figure PATH] [--figure-count N]

The world of each count N (`doorway_document`) is `doorway8` grown: two rooms joined by a door
of clear width DOOR_WIDTH (1.2 m, between the rounded tips of the jambs) in a wall along x = 0,
WALL_THICKNESS thick. N robots start in each room (radius 0.25 m, max speed 1 m/s) on a grid
of `grid_shape(N)` rows (along y, SPACING_Y apart, centred on y = 0) and columns (along x,
SPACING_X apart, the nearest NEAREST_X from the wall); each robot's goal is its start mirrored
through the door's centre, so every straight line from a start to its goal runs through that
centre and each robot has to cross. The rooms' inner faces are ROOM_MARGIN_X beyond the
farthest column and ROOM_MARGIN_Y beyond the outer rows. A run lasts at most DURATION_BASE +
DURATION_PER_PAIR N (30 s and 15 s a robot each way: 90 s for four each way, `doorway8`'s
duration), and ends sooner once every robot has been at its goal for 1 s. Four each way is
`doorway8`'s world and robots, at the planner's defaults instead of its `eta` 0.8 (Cantelli's).
Noise 0.05 on position, velocity and actuation, dt 0.1 s, goal tolerance 0.2 m, seeds from
FIRST_SEED. Each world is written as a scenario file in a temporary directory and read through
the scenario loader, so it is validated as a user's file is.

Each count is run by prvo on the in-process engine at the planner's defaults (`--planner
NAME=VALUE` over them, read as the wall benchmark reads it: `--planner right_of_way=false` for
the ablation) over `--seeds` consecutive seeds with noise, and noise-free by each of `--peers`
that is importable (RVO2's ORCA by default; neither peer is a dependency of prvo: see
`prvo_sim.bench.walls` for how each is given the walls, and for the row's measures: arrivals,
makespan, contacts with robots and walls, stalls, the longest time near one spot). The sweep
adds, from the trajectory alone:

* through: a robot is through the door at the first time its centre is beyond the wall's far
  face by its radius (`through_times`);
* throughput [robots/min] = 60 x (robots through) / T, T the time from the start to the last
  robot through when every robot got through, else the run's length (`throughput`). It is
  counted from the start, not from the first robot through: with one robot each way both may
  cross side by side at once (two 0.5 m robots fit the 1.2 m door), and the span between the
  first and the last crossing would then be near zero. Over seeds the robots through and the
  times T are added up;
* in the doorway: a robot's centre within the wall's thickness plus its radius of the wall's
  plane (|x| < WALL_THICKNESS / 2 + r) and within the door's half-width of its axis
  (`doorway_intervals`); `--figure` draws these intervals, one bar a robot coloured by the way
  it goes, beside the trajectories, for one prvo run: the first seed's of `--figure-count`, by
  default of the largest count every robot of that run completed (else the largest count).

Exit codes: 0 every prvo robot arrived (through the door and at its goal), 1 one did not, 2
bad input (one line naming the option), 130 when interrupted.
"""

import argparse
import math
import pathlib
import sys
import tempfile

import numpy as np
import yaml

from prvo_planner.stalls import SUMMARY_COLUMNS
from prvo_sim.bench.engine import report
from prvo_sim.bench.walls import (
    PEERS,
    combined,
    importable_peers,
    labelled,
    noise_label,
    peer_trajectory,
    peer_world,
    planner_overrides,
    prvo_trajectory,
    trajectory_row,
    with_planner,
)
from prvo_sim.scenario import load_scenario

DEFAULT_COUNTS = (1, 2, 4, 8, 12)
# Robots each way at most: 48 robots for up to 390 s of sim time a seed. Twelve each way (210 s)
# took 10-13 minutes a seed on a shared core; the planning grows with the neighbours, so 24 each
# way would take over an hour a seed (not measured).
MAX_COUNT = 24
DOOR_WIDTH = 1.2
WALL_THICKNESS = 0.1
RADIUS = 0.25
MAX_SPEED = 1.0
NOISE_STD = 0.05
NEAREST_X = 2.2
SPACING_X = 1.4
SPACING_Y = 1.6
ROOM_MARGIN_X = 1.4
ROOM_MARGIN_Y = 2.2
DURATION_BASE = 30.0
DURATION_PER_PAIR = 15.0
FIRST_SEED = 7
DEFAULT_PEERS = ('rvo2-orca',)
# The figure's colours of the two ways through the door (matplotlib's tab10 blue and orange).
WAY_COLOURS = {1: '#1f77b4', -1: '#ff7f0e'}
WAY_LABELS = {1: 'left to right', -1: 'right to left'}


def grid_shape(count):
    """Return (rows, columns) of COUNT robots a side: rows even (but for one), about square.

    rows = min(COUNT, 2 ceil(sqrt(COUNT / 4))): 1 x 1, 2 x 1, 2 x 2, 4 x 2, 4 x 3 for 1, 2, 4, 8
    and 12; columns = ceil(COUNT / rows).
    """
    rows = min(count, 2 * math.ceil(math.sqrt(count / 4.0)))
    return rows, math.ceil(count / rows)


def left_starts(count):
    """Return the starts (COUNT, 2) [m] of the robots in the left room, x < 0.

    The nearest columns fill first; listed farthest column first, top row first (`doorway8`'s
    order).
    """
    rows, columns = grid_shape(count)
    ys = (0.5 * (rows - 1) - np.arange(rows)) * SPACING_Y
    cells = [(-(NEAREST_X + column * SPACING_X), y) for column in range(columns) for y in ys]
    return np.array(sorted(cells[:count], key=lambda cell: (cell[0], -cell[1])))


def doorway_document(count):
    """Return the scenario document (a dict, as YAML reads it) of COUNT robots each way.

    Robots robot_0 ... robot_{COUNT-1} start in the left room, the rest in the right (their
    starts the left ones' mirrored in the wall); every goal is the start negated.
    """
    rows, columns = grid_shape(count)
    half_x = NEAREST_X + (columns - 1) * SPACING_X + ROOM_MARGIN_X
    half_y = 0.5 * (rows - 1) * SPACING_Y + ROOM_MARGIN_Y
    # Wall lines run along the middle of the wall: the rooms' inner faces are at half_x, half_y.
    x, y = half_x + 0.5 * WALL_THICKNESS, half_y + 0.5 * WALL_THICKNESS
    tip = 0.5 * DOOR_WIDTH + 0.5 * WALL_THICKNESS
    lines = [[[-x, y], [x, y]], [[-x, -y], [x, -y]], [[-x, -y], [-x, y]], [[x, -y], [x, y]],
             [[0.0, half_y], [0.0, tip]], [[0.0, -half_y], [0.0, -tip]]]
    left = left_starts(count)
    starts = np.vstack([left, left * [-1.0, 1.0]])
    return {
        'name': f'doorway{2 * count}',
        'description': f'Two rooms joined by a {DOOR_WIDTH:g} m door; {count} robots go through '
                       'it each way.',
        'seed': FIRST_SEED, 'dt': 0.1,
        'duration': DURATION_BASE + DURATION_PER_PAIR * count,
        'goal_tolerance': 0.2,
        'noise': {'position_std': NOISE_STD, 'velocity_std': NOISE_STD,
                  'actuation_std': NOISE_STD},
        'walls': [{'line': [[round(value, 6) for value in point] for point in line],
                   'thickness': WALL_THICKNESS} for line in lines],
        'robots': [{'name': f'robot_{index}', 'start': [round(float(value), 6) for value in start],
                    'goal': [round(-float(value), 6) + 0.0 for value in start],
                    'radius': RADIUS, 'max_speed': MAX_SPEED}
                   for index, start in enumerate(starts)],
    }


def write_doorway(folder, count):
    """Write COUNT's scenario file into FOLDER; return its path."""
    path = pathlib.Path(folder) / f'doorway{2 * count}.yaml'
    path.write_text(yaml.safe_dump(doorway_document(count), sort_keys=False))
    return path


def way_signs(goals):
    """Return each robot's way (N,): +1 left to right (goal at x > 0), -1 right to left."""
    return np.where(np.asarray(goals)[:, 0] > 0.0, 1, -1)


def through_times(times, positions, radii, goals):
    """Return the time [s] each robot is first through the door (N,), nan if never.

    TIMES (T,) [s], POSITIONS (T, N, 2) [m], RADII (N,), GOALS (N, 2) [m]: through once its
    centre is beyond the wall's far face (on its goal's side of x = 0) by its radius.
    """
    radii = np.asarray(radii, dtype=float)
    beyond = (way_signs(goals) * np.asarray(positions)[:, :, 0]
              >= 0.5 * WALL_THICKNESS + radii)
    first = np.argmax(beyond, axis=0)
    return np.where(beyond.any(axis=0), np.asarray(times, dtype=float)[first], np.nan)


def throughput(through, length):
    """Return robots per minute through the door: 60 x robots through / T, or None.

    THROUGH (N,) as `through_times` gives it, LENGTH the run's length [s]. T is the last robot's
    time through when every robot got through, else LENGTH; None when nobody got through.
    """
    crossed = np.count_nonzero(~np.isnan(through))
    if crossed == 0:
        return None
    return 60.0 * crossed / door_time(through, length)


def door_time(through, length):
    """Return T of `throughput` [s]: the last time through if all got through, else LENGTH."""
    return float(np.max(through)) if not np.isnan(through).any() else float(length)


def doorway_intervals(times, positions, radii):
    """Return per robot the [enter, leave) intervals [s] it spends in the doorway (N lists).

    In the doorway: |x| < WALL_THICKNESS / 2 + r and |y| < DOOR_WIDTH / 2 at a sample of TIMES
    (T,); an interval runs from its first sample in to the next sample out (to the last sample
    if it never leaves), so that a single sample in counts one step.
    """
    times = np.asarray(times, dtype=float)
    positions = np.asarray(positions, dtype=float)
    inside = ((np.abs(positions[:, :, 0]) < 0.5 * WALL_THICKNESS + np.asarray(radii))
              & (np.abs(positions[:, :, 1]) < 0.5 * DOOR_WIDTH))
    intervals = []
    for column in inside.T:
        # Edges of the runs of True: +1 where one starts, -1 one past where one ends.
        edges = np.diff(np.concatenate([[0], column.astype(int), [0]]))
        enters, leaves = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        intervals.append([(float(times[enter]), float(times[min(leave, len(times) - 1)]))
                          for enter, leave in zip(enters, leaves, strict=True)])
    return intervals


def door_row(scenario, times, positions, plan_ms):
    """Return the wall benchmark's row of one run with `through` and `door_s` (T) added."""
    radii = np.array([robot.radius for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    through = through_times(times, positions, radii, goals)
    return {**trajectory_row(scenario, times, positions, plan_ms),
            'through': int(np.count_nonzero(~np.isnan(through))),
            'door_s': door_time(through, times[-1])}


def sweep_row(rows, count, planner, noise, seeds):
    """Return one labelled table row of the runs ROWS of COUNT robots each way."""
    row = combined(rows)
    through = sum(item['through'] for item in rows)
    door_s = sum(item['door_s'] for item in rows)
    labels = labelled(row, f'doorway{2 * count}', planner, noise, seeds)
    return {'each_way': count, **labels, 'through': f'{through}/{row["robots"]}',
            'throughput_per_min': round(60.0 * through / door_s, 1) if through else None}


COLUMNS = (('each_way', 'each way'), ('planner', 'planner'), ('noise', 'noise'),
           ('seeds', 'seeds'), ('through', 'through the door'), ('arrivals', 'arrived'),
           ('makespan_s', 'makespan s'), ('throughput_per_min', 'robots/min'),
           ('min_separation_m', 'min robot separation m'), ('contacts', 'robot contacts'),
           ('wall_contacts', 'wall contacts'), *SUMMARY_COLUMNS)


def plot_door_timeline(path, scenario, times, positions, title):
    """Write a PNG to PATH: the run's doorway intervals per robot (left), its paths (right).

    One bar a robot for each time its centre is in the doorway (`doorway_intervals`), coloured
    by its way (WAY_COLOURS), robots ordered by their first time in it, so that batches taking
    turns show as runs of one colour; the trajectories beside it, in the same colours.
    """
    # Imported here: plotting chooses matplotlib's backend, which only the figure needs.
    from prvo_sim.plotting import draw_static_world, plt

    radii = np.array([robot.radius for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    ways = way_signs(goals)
    intervals = doorway_intervals(times, positions, radii)
    order = sorted(range(len(radii)), key=lambda robot: (
        intervals[robot][0][0] if intervals[robot] else math.inf, robot))
    figure, (timeline, paths) = plt.subplots(1, 2, figsize=(11.0, 4.6),
                                             gridspec_kw={'width_ratios': [1.2, 1.0]})
    for row, robot in enumerate(order):
        timeline.broken_barh([(enter, leave - enter) for enter, leave in intervals[robot]],
                             (row - 0.4, 0.8), color=WAY_COLOURS[ways[robot]])
    timeline.set_yticks(range(len(order)))
    timeline.set_yticklabels([scenario.robots[robot].name for robot in order], fontsize=6)
    timeline.set_ylim(len(order) - 0.5, -0.5)
    timeline.set_xlim(0.0, float(times[-1]))
    timeline.set_xlabel('time [s]')
    timeline.set_title('in the doorway (ordered by first entry)', fontsize=9)
    timeline.grid(True, axis='x', alpha=0.3)
    for way, colour in WAY_COLOURS.items():
        timeline.plot([], [], '-', linewidth=6, color=colour, label=WAY_LABELS[way])
    timeline.legend(loc='upper center', bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=7,
                    frameon=False)
    draw_static_world(paths, scenario.static_world)
    for robot, way in enumerate(ways):
        paths.plot(positions[:, robot, 0], positions[:, robot, 1], '-', linewidth=0.8,
                   alpha=0.7, color=WAY_COLOURS[way])
        paths.plot(*scenario.robots[robot].start, 's', markersize=4, color=WAY_COLOURS[way])
    paths.set_aspect('equal')
    paths.set_xlabel('x [m]')
    paths.set_ylabel('y [m]')
    paths.set_title('trajectories (squares: starts)', fontsize=9)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def build_parser():
    """Return the command-line parser of the doorway sweep."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.doorway_sweep',
        description='Doorway sweep: N robots each way through one 1.2 m door, prvo (in '
                    'process) beside its peers.')
    parser.add_argument('--counts', type=int, nargs='+', default=list(DEFAULT_COUNTS),
                        help=f'robots each way, 1 to {MAX_COUNT} (default: 1 2 4 8 12)')
    parser.add_argument('--seeds', type=int, default=3,
                        help=f'noisy prvo runs per count, seeds from {FIRST_SEED} (default: 3)')
    parser.add_argument('--planner', nargs='*', default=[], metavar='NAME=VALUE',
                        help='planner parameters of every prvo robot over the defaults '
                             '(values read as YAML)')
    parser.add_argument('--peers', nargs='*', default=list(DEFAULT_PEERS), choices=PEERS,
                        help='peers to run when importable (default: rvo2-orca; none: --peers)')
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"runs": [...], "notes": [...]} to this file')
    parser.add_argument('--figure', type=pathlib.Path, default=None,
                        help='write a PNG of one prvo run taking turns at the door')
    parser.add_argument('--figure-count', type=int, default=None,
                        help='the count whose first seed --figure draws (default: the largest '
                             'every robot completed)')
    return parser


def input_error(options):
    """Return the one-line reason OPTIONS cannot be run, or None."""
    for count in options.counts:
        if not 1 <= count <= MAX_COUNT:
            return f'--counts: {count} is not a count of robots each way (1 to {MAX_COUNT})'
    if options.seeds < 1:
        return f'--seeds: {options.seeds} is not a count (at least 1)'
    if options.figure_count is not None and options.figure_count not in options.counts:
        return f'--figure-count: {options.figure_count} is not one of --counts'
    try:
        planner_overrides(options.planner)
    except ValueError as error:
        return str(error)
    return None


def count_rows(folder, count, options, peers):
    """Run COUNT robots each way; return (rows, the first seed's run).

    The run is (scenario, times (T,), positions (T, N, 2), whether every robot arrived).
    """
    overrides = planner_overrides(options.planner)
    path = write_doorway(folder, count)
    scenario = load_scenario(path)
    chosen = ''.join(f' {item}' for item in options.planner)
    runs, first = [], None
    for offset in range(options.seeds):
        seeded = with_planner(load_scenario(path, seed=scenario.seed + offset), overrides)
        trajectory = prvo_trajectory(seeded, 'prvo')
        runs.append(door_row(seeded, *trajectory))
        if first is None:
            first = (seeded, *trajectory[:2], runs[-1]['arrived'] == runs[-1]['robots'])
        print(f'{count} each way, seed {seeded.seed}: {runs[-1]["through"]}/'
              f'{runs[-1]["robots"]} through, {runs[-1]["arrived"]} arrived', flush=True)
    seeds = (str(scenario.seed) if options.seeds == 1
             else f'{scenario.seed}-{scenario.seed + options.seeds - 1}')
    rows = [sweep_row(runs, count, f'prvo{chosen}', noise_label(scenario), seeds)]
    for peer in peers:
        rows.append(sweep_row([door_row(scenario, *peer_trajectory(peer, peer_world(scenario)))],
                              count, peer, 'none', '-'))
        print(f'{count} each way, {peer}: {rows[-1]["through"]} through, '
              f'{rows[-1]["arrivals"]} arrived', flush=True)
    return rows, first


def main(argv=None):
    """Run the doorway sweep's command line; return the exit code."""
    options = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    error = input_error(options)
    if error is not None:
        print(f'prvo_sim.bench.doorway_sweep: error: {error}', file=sys.stderr)
        return 2
    notes = []
    peers = importable_peers(options.peers, notes)
    rows, firsts = [], {}
    try:
        with tempfile.TemporaryDirectory() as folder:
            for count in options.counts:
                runs, firsts[count] = count_rows(folder, count, options, peers)
                rows += runs
    except KeyboardInterrupt:
        print('prvo_sim.bench.doorway_sweep: interrupted', file=sys.stderr)
        return 130
    report(rows, COLUMNS, notes, options.json)
    if options.figure is not None:
        count = options.figure_count or max(
            (count for count, (*_, completed) in firsts.items() if completed),
            default=max(firsts))
        scenario, times, positions, _ = firsts[count]
        options.figure.parent.mkdir(parents=True, exist_ok=True)
        plot_door_timeline(options.figure, scenario, times, positions,
                           f'{count} robots each way through a {DOOR_WIDTH:g} m door, prvo'
                           f'{"".join(f" {item}" for item in options.planner)}, seed '
                           f'{scenario.seed}')
    prvo = [row for row in rows if row['planner'].startswith('prvo')]
    return 0 if all(row['arrived'] == row['robots'] for row in prvo) else 1


if __name__ == '__main__':
    sys.exit(main())
