"""
Benchmark of ``plan_velocity`` and ``plan_velocities``: time per call and per robot-step.

Usage: ``python -m prvo_planner.bench [--json PATH] [--repeats R] [--clock wall|cpu]``. Every
model is timed on the same seeded random encounters for N neighbours in {1, 5, 10, 20, 50} and
M directions in {16, 64, 128}. ``--clock cpu`` times with the process CPU clock, which is
insensitive to other processes competing for the cores.

``python -m prvo_planner.bench --team [--robots 10 20] [--json PATH] [--clock wall|cpu]``: teams
swap sides of a circle in a noise-free closed loop of the core alone; every step is planned once
by ``plan_velocities`` for the whole team and once by ``plan_velocity`` per robot (the two must
agree bit for bit), and both are timed per robot-step.

``python -m prvo_planner.bench --obstacles [--json PATH] [--repeats R] [--clock wall|cpu]``:
the ego of each seeded encounter (N neighbours in {0, 1, 5, 10, 20}, 64 directions, prvo) is
planned with and without 50 seeded wall segments around it (``bench_walls``), alternately, and
the ratio of the median times is reported with the plan's feasibility either way.

``python -m prvo_planner.bench --profile [--repeats R] [--top K] [--json PATH] [--clock
wall|cpu]``: one plan at the planner node's defaults (certified bound, eta 0.95, M = 64, no
actuation noise) of the encounters of 10, 20 and 50 neighbours, without
and with the walls of ``bench_walls``: its time per call, then the same calls under cProfile
(timed by the same clock): Python function calls and calls of numpy's Python functions and C
methods per plan, the compiled kernels' share (their self time, native code the profiler only
enters and leaves: what a plan costs with no Python around the kernels), and the functions of
``prvo_planner.core`` that take the most time, by cumulative and by self time. A function's
self time includes the numpy arithmetic its operators (``a * b``) and ufuncs run, which cProfile
does not see as calls.
"""

import argparse
import cProfile
import importlib
import json
import os
import pstats
import sys
import time

from numba.core.dispatcher import Dispatcher
import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocities, plan_velocity
from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.encounters import EncounterDistribution, random_encounter
from prvo_planner.heap import keep_freed_heap
from prvo_planner.parameters import planner_config_from

NEIGHBOURS = (1, 5, 10, 20, 50)
DIRECTIONS = (16, 64, 128)
VARIANTS = (
    ('prvo-exact', {'model': 'prvo', 'method': 'exact'}),
    ('prvo-certified', {'model': 'prvo', 'method': 'exact', 'certificate': 'certified'}),
    ('prvo-taylor', {'model': 'prvo', 'method': 'taylor'}),
    ('rvo', {'model': 'rvo'}),
    ('inflate', {'model': 'inflate'}),
    ('mc', {'model': 'mc', 'mc_samples': 1000}),
)


def bench_encounter(count):
    """Return the seeded encounter of COUNT neighbours within 8 m that each variant is timed on."""
    return random_encounter(np.random.default_rng(count), EncounterDistribution(
        neighbours=(count, count), distance=(1.0, 8.0), approach_speed=(-1.0, 1.0),
        velocity_scatter=0.5, ego_velocity=(0.0, 0.8), position_std=(0.05, 0.1),
        velocity_std=(0.05, 0.1)))


def time_calls(ego, neighbours, config, repeats, clock=time.perf_counter, obstacles=None):
    """Time ``repeats`` calls (milliseconds) after one warm-up call."""
    plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=obstacles)
    times = []
    for _ in range(repeats):
        start = clock()
        plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=obstacles)
        times.append(1e3 * (clock() - start))
    return np.array(times)


OBSTACLE_NEIGHBOURS = (0, 1, 5, 10, 20)
WALL_COUNT = 50


def bench_walls(count=WALL_COUNT, seed=0):
    """
    Return COUNT seeded wall segments around an ego at the origin (radius 0.3 m).

    Half of them form a corridor beside the ego (two rows of 1-2.5 m pieces with 0.3-1 m gaps
    along ``y = -1.2`` and ``y = +1.2``, from ``x = -4``), the others lie at random 3-10 m away
    (length 0.5-3 m, any orientation); thickness 0.1 m.
    """
    rng = np.random.default_rng(seed)
    segments = []
    for side in (-1.2, 1.2):
        x = -4.0
        for _ in range(count // 4):
            length = rng.uniform(1.0, 2.5)
            segments.append([[x, side], [x + length, side]])
            x += length + rng.uniform(0.3, 1.0)
    while len(segments) < count:
        distance, bearing, heading = rng.uniform(3.0, 10.0), *rng.uniform(0.0, 2.0 * np.pi, 2)
        middle = distance * np.array([np.cos(bearing), np.sin(bearing)])
        half = 0.5 * rng.uniform(0.5, 3.0) * np.array([np.cos(heading), np.sin(heading)])
        segments.append([middle - half, middle + half])
    return StaticObstacles(np.array(segments), np.full(count, 0.05), np.zeros((0, 2)),
                           np.zeros(0))


def run_obstacles(repeats, clock=time.perf_counter):
    """Time the ego of each encounter with and without the walls of ``bench_walls``."""
    walls = bench_walls()
    config = PlannerConfig(max_speed=1.0, num_directions=64, actuation_cov=0.01 * np.eye(2),
                           seed=0)
    rows = []
    for count in OBSTACLE_NEIGHBOURS:
        ego, neighbours = bench_encounter(max(count, 1))
        neighbours = neighbours[:count]
        # Alternated, so that other load on the machine slows both alike.
        free, walled = np.median([[time_calls(ego, neighbours, config, 1, clock)[0],
                                   time_calls(ego, neighbours, config, 1, clock, walls)[0]]
                                  for _ in range(repeats)], axis=0)
        result = plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=walls)
        plain = plan_velocity(ego, neighbours, [1.0, 0.0], config)
        rows.append({'neighbours': count, 'walls': len(walls.segments),
                     'without_ms': float(free), 'with_ms': float(walled),
                     'ratio': float(walled / free), 'feasible_without': plain.feasible,
                     'feasible_with': result.feasible,
                     'clearance': result.obstacle_clearance,
                     'obstacle_probability': result.obstacle_probability})
    return rows


def obstacle_table(rows):
    """Markdown table: median ms per plan without and with the walls, and their ratio."""
    lines = ['| neighbours | walls | without ms | with ms | ratio | feasible without / with '
             '| clearance m | P(obstacles) |', '|---|---|---|---|---|---|---|---|']
    for row in rows:
        lines.append(f"| {row['neighbours']} | {row['walls']} | {row['without_ms']:.3f} "
                     f"| {row['with_ms']:.3f} | {row['ratio']:.2f} "
                     f"| {row['feasible_without']} / {row['feasible_with']} "
                     f"| {row['clearance']:.2f} | {row['obstacle_probability']:.3f} |")
    return '\n'.join(lines)


PROFILE_NEIGHBOURS = (10, 20, 50)
PROFILE_TOP = 12
CORE_DIRECTORY = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'core') + os.sep


def profile_config():
    """Return the planner node's default PlannerConfig."""
    return planner_config_from({})


def _function_name(key):
    """Name a pstats key (file, line, function): ``module.function`` for prvo's core."""
    filename, _, function = key
    if filename.startswith(CORE_DIRECTORY):
        return f'{os.path.basename(filename)[:-3]}.{function}'
    return function


def _is_numpy(key):
    """Whether a pstats key is a function of numpy (Python, or a C method or function)."""
    filename, _, function = key
    return (f'{os.sep}numpy{os.sep}' in filename
            or (filename == '~' and ('numpy' in function or 'ufunc' in function)))


def compiled_kernel(key):
    """Whether a pstats key (file, line, function) is a compiled kernel of prvo's core.

    The core's numba dispatchers: cProfile sees each call as one of its Python function, and
    its self time is the native code's (the engine benchmark's profile counts them too).
    """
    filename, _, function = key
    if not filename.startswith(CORE_DIRECTORY):
        return False
    module = importlib.import_module(
        f'prvo_planner.core.{os.path.basename(filename)[:-3]}')
    return isinstance(getattr(module, function, None), Dispatcher)


def profile_case(ego, neighbours, config, repeats, clock, obstacles):
    """
    Time and profile ``repeats`` plans of one encounter; return its row.

    The row holds the median and p95 time per plan without the profiler [ms], the profiled
    time per plan, calls per plan (every Python function, numpy's functions and methods, the
    functions of ``prvo_planner.core``), the compiled kernels' time per plan (their self time
    under the profiler, which adds only its cost per call to native code) and per function of
    the core its calls, self and cumulative time per plan [ms].
    """
    times = time_calls(ego, neighbours, config, repeats, clock, obstacles)
    profiler = cProfile.Profile(clock)
    profiler.enable()
    for _ in range(repeats):
        plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=obstacles)
    profiler.disable()
    stats = pstats.Stats(profiler).stats
    core = {key: value for key, value in stats.items() if key[0].startswith(CORE_DIRECTORY)}
    return {'neighbours': len(neighbours),
            'walls': 0 if obstacles is None else len(obstacles.segments),
            'median_ms': float(np.median(times)), 'p95_ms': float(np.percentile(times, 95)),
            'profiled_ms': 1e3 * sum(value[2] for value in stats.values()) / repeats,
            'calls': sum(value[1] for value in stats.values()) / repeats,
            'numpy_calls': sum(value[1] for key, value in stats.items()
                               if _is_numpy(key)) / repeats,
            'core_calls': sum(value[1] for value in core.values()) / repeats,
            'core_self_ms': 1e3 * sum(value[2] for value in core.values()) / repeats,
            'compiled_ms': 1e3 * sum(value[2] for key, value in core.items()
                                     if compiled_kernel(key)) / repeats,
            'functions': {_function_name(key): {'calls': value[1] / repeats,
                                                'self_ms': 1e3 * value[2] / repeats,
                                                'cumulative_ms': 1e3 * value[3] / repeats}
                          for key, value in core.items()}}


def run_profile(repeats, clock=time.perf_counter):
    """Profile the default plan of each encounter of PROFILE_NEIGHBOURS, without and with walls."""
    config, walls = profile_config(), bench_walls()
    rows = []
    for count in PROFILE_NEIGHBOURS:
        ego, neighbours = bench_encounter(count)
        rows.extend(profile_case(ego, neighbours, config, repeats, clock, obstacles)
                    for obstacles in (None, walls))
    return rows


def _case(row):
    return f"{row['neighbours']}{' + walls' if row['walls'] else ''}"


def profile_tables(rows, top=PROFILE_TOP):
    """
    Markdown tables of profiled rows: the plans, then the core's top functions by each time.

    A function is listed if it is among the TOP of any row; each cell is its ms per plan and
    its share of the profiled plan.
    """
    lines = ['| neighbours | walls | median / p95 ms | compiled kernels ms | profiled ms '
             '| Python calls | numpy calls | core calls | core self ms (share) |',
             '|---|---|---|---|---|---|---|---|---|']
    for row in rows:
        lines.append(f"| {row['neighbours']} | {row['walls']} | {row['median_ms']:.2f} / "
                     f"{row['p95_ms']:.2f} | {row['compiled_ms']:.2f} | "
                     f"{row['profiled_ms']:.2f} | {row['calls']:.0f} | "
                     f"{row['numpy_calls']:.0f} | {row['core_calls']:.0f} | "
                     f"{row['core_self_ms']:.2f} ({row['core_self_ms'] / row['profiled_ms']:.0%})"
                     ' |')
    for measure in ('cumulative_ms', 'self_ms'):
        names = []
        for row in rows:
            ranked = sorted(row['functions'], key=lambda name: -row['functions'][name][measure])
            names.extend(name for name in ranked[:top] if name not in names)
        names.sort(key=lambda name: -max(row['functions'].get(name, {measure: 0.0})[measure]
                                         for row in rows))
        lines += ['', f"{measure.split('_')[0]} ms per plan (share of the profiled plan)",
                  '| function | calls per plan | '
                  + ' | '.join(_case(row) for row in rows) + ' |',
                  '|---|---|' + '---|' * len(rows)]
        for name in names:
            cells = [row['functions'].get(name) for row in rows]
            calls = [cell['calls'] for cell in cells if cell is not None]
            lines.append(f'| {name} | {min(calls):.3g}-{max(calls):.3g} | ' + ' | '.join(
                '-' if cell is None
                else f"{cell[measure]:.2f} ({cell[measure] / row['profiled_ms']:.0%})"
                for cell, row in zip(cells, rows, strict=True)) + ' |')
    return '\n'.join(lines)


def run(repeats, mc_repeats, clock=time.perf_counter):
    """Time every variant; return the result rows."""
    rows = []
    for count in NEIGHBOURS:
        ego, neighbours = bench_encounter(count)
        for directions in DIRECTIONS:
            for name, options in VARIANTS:
                config = PlannerConfig(max_speed=1.0, num_directions=directions,
                                       actuation_cov=0.01 * np.eye(2), seed=0, **options)
                times = time_calls(ego, neighbours, config,
                                   mc_repeats if options['model'] == 'mc' else repeats, clock)
                rows.append({'model': name, 'neighbours': count, 'directions': directions,
                             'median_ms': float(np.median(times)),
                             'p95_ms': float(np.percentile(times, 95))})
    return rows


def table(rows):
    """Markdown table: one row per (N, M), median / p95 ms per model."""
    names = [name for name, _ in VARIANTS]
    lines = ['| N | M | ' + ' | '.join(names) + ' |', '|---|---|' + '---|' * len(names)]
    for count in NEIGHBOURS:
        for directions in DIRECTIONS:
            cells = {row['model']: row for row in rows
                     if row['neighbours'] == count and row['directions'] == directions}
            lines.append(f'| {count} | {directions} | ' + ' | '.join(
                f"{cells[name]['median_ms']:.3g} / {cells[name]['p95_ms']:.3g}"
                for name in names) + ' |')
    return '\n'.join(lines)


# The circle swap of --team: node defaults, noise stds 0.05 (m, m/s) in every belief and in the
# actuation model, 0.1 s steps.
TEAM_SIZES = (10, 20)
TEAM_DT = 0.1
TEAM_STD = 0.05
TEAM_GOAL_TOLERANCE = 0.2
TEAM_MAX_STEPS = 600


def team_config():
    """Return the planner configuration of every robot of the circle swap (node defaults)."""
    return PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=TEAM_STD ** 2 * np.eye(2),
                         inertia=0.5, passing_bias=0.1, progress_weight=0.5)


def circle_swap(count, config, seed=0, planner=None):
    """
    Run a noise-free circle swap of ``count`` robots and yield every step's planning inputs.

    Robots of radius 0.2-0.3 m (seeded) start evenly on a circle of radius ``max(4, N / 4)`` m
    and head for the opposite point at up to ``config.max_speed``, slowing over the last metre
    and wanting to stay once within the goal tolerance. Beliefs are the true states with a
    fixed covariance. Each step's commands come from
    ``planner(egos, neighbours_per_ego, v_prefs, previous)`` (``plan_velocities`` by default);
    the loop ends when every robot has reached its goal or after ``TEAM_MAX_STEPS``.

    Yields
    ------
    tuple
        ``(egos, neighbours_per_ego, v_prefs, previous)`` of the step, before it is planned.

    """
    if planner is None:
        def planner(egos, neighbours, v_prefs, previous):
            return plan_velocities(egos, neighbours, v_prefs, config, previous)
    rng = np.random.default_rng(seed)
    angles = 2.0 * np.pi * np.arange(count) / count
    positions = max(4.0, count / 4.0) * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    goals = -positions
    radii = rng.uniform(0.2, 0.3, size=count)
    velocities = np.zeros((count, 2))
    covariance = TEAM_STD ** 2 * np.eye(4)
    arrived = np.zeros(count, dtype=bool)
    for _ in range(TEAM_MAX_STEPS):
        to_goal = goals - positions
        distance = np.hypot(to_goal[:, 0], to_goal[:, 1])
        # A robot that has reached its goal once wants to stay (as the node does).
        arrived |= distance < TEAM_GOAL_TOLERANCE
        if arrived.all():
            return
        speed = np.where(arrived, 0.0, np.minimum(config.max_speed, distance))
        v_prefs = to_goal * (speed / np.maximum(distance, 1e-12))[:, None]
        egos = [AgentBelief(positions[i], velocities[i], covariance, radii[i])
                for i in range(count)]
        neighbours = [egos[:i] + egos[i + 1:] for i in range(count)]
        previous = list(velocities)
        yield egos, neighbours, list(v_prefs), previous
        velocities = np.array([result.velocity
                               for result in planner(egos, neighbours, list(v_prefs), previous)])
        positions = positions + TEAM_DT * velocities


def same_plan(first, second):
    """Whether two PlanResults are equal bit for bit."""
    return (np.array_equal(first.velocity, second.velocity)
            and np.array_equal(first.achieved_k, second.achieved_k)
            and np.array_equal(first.eta_bound, second.eta_bound)
            and np.array_equal(first.neighbour_bounds, second.neighbour_bounds)
            and first.bound_kinds == second.bound_kinds
            and (first.feasible, first.num_constraints, first.candidates_feasible)
            == (second.feasible, second.num_constraints, second.candidates_feasible))


def run_team(count, clock=time.perf_counter):
    """Time both calls on every step of a circle swap of ``count`` robots; return a row."""
    config = team_config()
    batched, single, steps, different = [], [], 0, 0

    def timed_planner(egos, neighbours, v_prefs, previous):
        nonlocal different
        start = clock()
        team = plan_velocities(egos, neighbours, v_prefs, config, previous)
        batched.append(clock() - start)
        start = clock()
        alone = [plan_velocity(egos[i], neighbours[i], v_prefs[i], config, previous[i])
                 for i in range(count)]
        single.append(clock() - start)
        different += sum(not same_plan(a, b) for a, b in zip(team, alone, strict=True))
        return team

    for _ in circle_swap(count, config, planner=timed_planner):
        steps += 1
    batched, single = 1e3 * np.array(batched) / count, 1e3 * np.array(single) / count
    return {'robots': count, 'steps': steps,
            'batched_median_ms': float(np.median(batched)),
            'batched_mean_ms': float(np.mean(batched)),
            'single_median_ms': float(np.median(single)),
            'single_mean_ms': float(np.mean(single)), 'different_plans': int(different)}


def team_table(rows):
    """Markdown table: ms per robot-step, batched and one robot at a time."""
    lines = ['| robots | steps | plan_velocities ms/robot-step median / mean '
             '| plan_velocity ms/robot-step median / mean | different plans |',
             '|---|---|---|---|---|']
    for row in rows:
        lines.append(f"| {row['robots']} | {row['steps']} | {row['batched_median_ms']:.3f} / "
                     f"{row['batched_mean_ms']:.3f} | {row['single_median_ms']:.3f} / "
                     f"{row['single_mean_ms']:.3f} | {row['different_plans']} |")
    return '\n'.join(lines)


def main(argv=None):
    """Run the benchmark, print a Markdown table, optionally write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--json', metavar='PATH', help='write {"results": [...]} here')
    parser.add_argument('--repeats', type=int, default=50, help='timed calls per cell')
    parser.add_argument('--mc-repeats', type=int, default=5, help='timed calls per mc cell')
    parser.add_argument('--clock', choices=('wall', 'cpu'), default='wall',
                        help='wall time (default) or process CPU time')
    parser.add_argument('--team', action='store_true',
                        help='time plan_velocities per robot-step on circle swaps instead')
    parser.add_argument('--robots', type=int, nargs='+', default=list(TEAM_SIZES),
                        help='team sizes of --team')
    parser.add_argument('--obstacles', action='store_true',
                        help=f'time plans beside {WALL_COUNT} wall segments against plans '
                        'without them instead')
    parser.add_argument('--profile', action='store_true',
                        help='profile default plans (certified, with and without walls) instead')
    parser.add_argument('--top', type=int, default=PROFILE_TOP,
                        help='functions of each --profile row listed per table')
    arguments = parser.parse_args(argv)
    keep_freed_heap()
    clock = time.perf_counter if arguments.clock == 'wall' else time.process_time
    if arguments.profile:
        rows = run_profile(arguments.repeats, clock)
        print(f'default plans, per plan_velocity call ({arguments.clock} clock)')
        print(profile_tables(rows, arguments.top))
    elif arguments.obstacles:
        rows = run_obstacles(arguments.repeats, clock)
        print(f'median ms per plan_velocity call, with and without walls ({arguments.clock} '
              'clock)')
        print(obstacle_table(rows))
    elif arguments.team:
        if min(arguments.robots) < 2:
            parser.error(f'--robots must all be >= 2, got {arguments.robots}')
        rows = [run_team(count, clock) for count in arguments.robots]
        print(f'ms per robot-step on circle swaps ({arguments.clock} clock)')
        print(team_table(rows))
    else:
        rows = run(arguments.repeats, arguments.mc_repeats, clock)
        print(f'median / p95 ms per plan_velocity call ({arguments.clock} clock)')
        print(table(rows))
    if arguments.json:
        with open(arguments.json, 'w', encoding='utf-8') as stream:
            json.dump({'results': rows}, stream, indent=2)
    return 0


if __name__ == '__main__':
    sys.exit(main())
