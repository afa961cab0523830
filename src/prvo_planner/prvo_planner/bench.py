"""
Benchmark of ``plan_velocity``: median and p95 time per call.

Usage: ``python -m prvo_planner.bench [--json PATH] [--repeats R] [--clock wall|cpu]``. Every
model is timed on the same seeded random encounters for N neighbours in {1, 5, 10, 20, 50} and
M directions in {16, 64, 128}. ``--clock cpu`` times with the process CPU clock, which is
insensitive to other processes competing for the cores.
"""

import argparse
import json
import sys
import time

import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity

NEIGHBOURS = (1, 5, 10, 20, 50)
DIRECTIONS = (16, 64, 128)
VARIANTS = (
    ('prvo-exact', {'model': 'prvo', 'method': 'exact'}),
    ('prvo-taylor', {'model': 'prvo', 'method': 'taylor'}),
    ('rvo', {'model': 'rvo'}),
    ('inflate', {'model': 'inflate'}),
    ('mc', {'model': 'mc', 'mc_samples': 1000}),
)


def random_covariance(rng, position_std, velocity_std):
    """Random full 4x4 covariance with the given typical standard deviations."""
    scales = np.array([position_std, position_std, velocity_std, velocity_std])
    factor = rng.normal(size=(4, 4)) * 0.5 + np.eye(4)
    return (scales[:, None] * (factor @ factor.T) * scales[None, :]) / 2.0


def random_encounter(rng, count):
    """Draw an ego robot at the origin heading +x and ``count`` neighbours within 8 m."""
    ego = AgentBelief([0.0, 0.0], [0.8, 0.0], random_covariance(rng, 0.05, 0.05), 0.3)
    neighbours = []
    for _ in range(count):
        while True:
            position = rng.uniform(-8.0, 8.0, size=2)
            if np.hypot(*position) > 1.0:
                break
        neighbours.append(AgentBelief(position, rng.uniform(-1.0, 1.0, size=2),
                                      random_covariance(rng, 0.1, 0.1), 0.3))
    return ego, neighbours


def time_calls(ego, neighbours, config, repeats, clock=time.perf_counter):
    """Time ``repeats`` calls (milliseconds) after one warm-up call."""
    plan_velocity(ego, neighbours, [1.0, 0.0], config)
    times = []
    for _ in range(repeats):
        start = clock()
        plan_velocity(ego, neighbours, [1.0, 0.0], config)
        times.append(1e3 * (clock() - start))
    return np.array(times)


def run(repeats, mc_repeats, clock=time.perf_counter):
    """Time every variant; return the result rows."""
    rows = []
    for count in NEIGHBOURS:
        ego, neighbours = random_encounter(np.random.default_rng(count), count)
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


def main(argv=None):
    """Run the benchmark, print a Markdown table, optionally write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--json', metavar='PATH', help='write {"results": [...]} here')
    parser.add_argument('--repeats', type=int, default=50, help='timed calls per cell')
    parser.add_argument('--mc-repeats', type=int, default=5, help='timed calls per mc cell')
    parser.add_argument('--clock', choices=('wall', 'cpu'), default='wall',
                        help='wall time (default) or process CPU time')
    arguments = parser.parse_args(argv)
    clock = time.perf_counter if arguments.clock == 'wall' else time.process_time
    rows = run(arguments.repeats, arguments.mc_repeats, clock)
    print(f'median / p95 ms per plan_velocity call ({arguments.clock} clock)')
    print(table(rows))
    if arguments.json:
        with open(arguments.json, 'w', encoding='utf-8') as stream:
            json.dump({'results': rows}, stream, indent=2)
    return 0


if __name__ == '__main__':
    sys.exit(main())
