"""Whether the planners' beliefs are as uncertain as they claim, against the simulator's truth.

`python -m prvo_sim.bench.calibration SCENARIO [--seeds 7 8 ...] [--method prvo] [--eta ETA]
[--certificate cantelli|certified] [--json PATH]` runs SCENARIO on the in-process engine. At
every plan it compares each belief a planner holds, its own and each neighbour's, with the
ground truth of that stamp: the normalised estimation error squared `e' P^-1 e` of the position
and of the velocity. Each has 2 degrees of freedom:
when the covariances are right its mean is 2 and 5% of the values exceed 5.99 (the 95% ellipse).
A larger mean is an overconfident tracker, and the chance constraint's probability is stated
over beliefs that understate the error. Rows: own beliefs, planned neighbours, scripted
neighbours (they change velocity only by actuation noise and at waypoints).
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from prvo_planner.core.config import CERTIFICATES
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario

# The 95% quantile of chi-squared with 2 degrees of freedom: -2 ln(0.05).
CHI2_2_95 = -2.0 * np.log(0.05)
KINDS = ('own', 'planned neighbour', 'scripted neighbour')


def squared_errors(belief, truth):
    """Return (position, velocity) NEES of a StateBelief against a truth row [x, y, vx, vy]."""
    error = belief.mean - truth[:4]
    return tuple(float(error[part] @ np.linalg.solve(belief.covariance[part, part], error[part]))
                 for part in (slice(0, 2), slice(2, 4)))


def run_seed(scenario, method, eta=None, certificate=None):
    """Run SCENARIO until every planned robot has arrived; return {kind: [(pos, vel), ...]}.

    ETA and CERTIFICATE, if given, replace every planner's.
    """
    chosen = {} if certificate is None else {'certificate': certificate}
    values = [None if robot.scripted is not None
              else {**planner_values(robot, scenario, method, eta), **chosen}
              for robot in scenario.robots]
    team = InProcessTeam(scenario, values)
    index_of = {name: index for index, name in enumerate(team.world.names)}
    scripted = {robot.name for robot in scenario.robots if robot.scripted is not None}
    errors = {kind: [] for kind in KINDS}
    planned = [(index, agent) for index, agent in enumerate(team.agents) if agent is not None]
    while not team.finished:
        record = team.do_step()
        for (index, _), request in zip(planned, team.last_requests, strict=True):
            errors['own'].append(squared_errors(request.own, record.states[index]))
            for name, belief in zip(request.neighbour_names, request.neighbours, strict=True):
                kind = 'scripted neighbour' if name in scripted else 'planned neighbour'
                errors[kind].append(squared_errors(belief, record.states[index_of[name]]))
        if all(agent.arrived for _, agent in planned):
            break
    return errors


def summary(values):
    """Return the row of a list of (position, velocity) NEES pairs."""
    values = np.asarray(values, dtype=float).reshape(-1, 2)
    return {'beliefs': int(values.shape[0]),
            **{f'{part}_{stat}': round(float(value), 3) for part, column in (
                ('position', values[:, 0]), ('velocity', values[:, 1])) for stat, value in (
                    ('mean_nees', column.mean() if column.size else np.nan),
                    ('beyond_95', (column > CHI2_2_95).mean() if column.size else np.nan))}}


def build_parser():
    """Return the command line's parser."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.calibration',
        description="Normalised estimation errors of the planners' beliefs against the truth "
                    '(in-process engine).')
    parser.add_argument('scenario', help='scenario YAML file (or the name of a shipped one)')
    parser.add_argument('--seeds', type=int, nargs='+', default=[7],
                        help='noise seeds, one run each (default: 7)')
    parser.add_argument('--method', default='prvo', choices=('prvo', 'rvo', 'inflate', 'mc'),
                        help='planner model (default: prvo)')
    parser.add_argument('--eta', type=float, default=None,
                        help="every planner's eta, in (0, 1) (default: the scenario's)")
    parser.add_argument('--certificate', choices=CERTIFICATES, default=None,
                        help="every planner's bound (default: the scenario's, else the "
                             "planner's)")
    parser.add_argument('--json', type=pathlib.Path, help='also write the rows to this file')
    return parser


def main(argv=None):
    """Print the calibration table of a scenario; exit 2 on a bad scenario."""
    options = build_parser().parse_args(argv)
    if options.eta is not None and not 0.0 < options.eta < 1.0:
        print(f'prvo_sim.bench.calibration: --eta: {options.eta} is not a probability in (0, 1)',
              file=sys.stderr)
        return 2
    errors = {kind: [] for kind in KINDS}
    try:
        path = find_scenario(options.scenario)
        for seed in options.seeds:
            for kind, values in run_seed(load_scenario(path, seed), options.method,
                                         options.eta, options.certificate).items():
                errors[kind] += values
    except ScenarioError as error:
        print(f'prvo_sim.bench.calibration: {error}', file=sys.stderr)
        return 2
    rows = {kind: summary(values) for kind, values in errors.items() if values}
    print(f'{options.scenario}, {options.method}, seeds {options.seeds} '
          '(calibrated: mean 2, 0.05 beyond the 95% ellipse)')
    print('| beliefs of | count | position mean NEES | beyond 95% | velocity mean NEES | '
          'beyond 95% |')
    print('|---|---|---|---|---|---|')
    for kind, row in rows.items():
        print(f"| {kind} | {row['beliefs']} | {row['position_mean_nees']} | "
              f"{row['position_beyond_95']} | {row['velocity_mean_nees']} | "
              f"{row['velocity_beyond_95']} |")
    if options.json is not None:
        options.json.write_text(json.dumps(rows, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
