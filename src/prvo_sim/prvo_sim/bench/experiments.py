"""Reproduce the PRVO paper's section 6 (and a little more); write a Markdown report.

    experiments --out results/paper [--seeds 10] [--quick]
    experiments --out DIR --methods-only --variants certificates   # the bound's table alone

Items 1, 3 and 4 (Cantelli validation, the ego-noise ablation, time-scaling intervals against
radius enlargement) use the planning core directly. Item 2 (deviation against k) and item 5
(methods over the shipped scenarios, one run per scenario, method and seed) run the team loop
on the in-process engine: the same world and planners as the ROS lockstep run, without
processes. Item 5 also measures the exact-against-Taylor error of the ray solver. Its rows are
the methods (`--variants methods`) or the bounds a velocity meets eta by (`--variants
certificates`: Cantelli's at 0.8, the certified Gaussian bound at 0.8, 0.9, 0.95 and 0.99).
"""

import argparse
import dataclasses
import json
import math
import pathlib
import subprocess
import sys
import time

import numpy as np
import yaml

from prvo_planner import encounters
from prvo_planner.agent import preferred_velocity
from prvo_planner.core import (
    AgentBelief,
    PlannerConfig,
    eta_from_k,
    k_from_eta,
    plan_velocity,
    rvo_moments,
)
from prvo_planner.core.probability import confidence_ellipse_scale, rvo_condition_of
from prvo_planner.parameters import DEFAULTS
from prvo_sim import metrics
from prvo_sim.engine import InProcessTeam
from prvo_sim.plotting import draw_trajectories, plt, robot_colours
from prvo_sim.runner.outputs import Ending
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import NoiseSpec, find_scenario, load_scenario

SNAPSHOT_DISTANCE = 2.0  # m from the meeting point: the robots are closing in at full speed
VALIDATION_KS = (1.0, 1.5)
DEVIATION_KS = (0.5, 1.0, 1.5, 2.0, 3.0)
CONFIDENCE_LEVELS = (0.68, 0.80)
SCENARIOS = ('circle8', 'crossing4', 'headon2', 'parked_large', 'mixed12')
# (label, runner method, eta, certificate); eta None leaves the scenario's (rvo ignores it),
# certificate None the planner's default (only prvo certifies).
METHOD_VARIANTS = (('prvo eta 0.5', 'prvo', 0.5, 'cantelli'),
                   ('prvo eta 0.8', 'prvo', 0.8, 'cantelli'),
                   ('prvo eta 0.9', 'prvo', 0.9, 'cantelli'), ('rvo', 'rvo', None, None),
                   ('inflate eta 0.8', 'inflate', 0.8, None),
                   ('prvo-no-ego eta 0.8', 'prvo-no-ego', 0.8, 'cantelli'))
# The choice of the default: Cantelli's bound at the old default against the certified bound.
CERTIFICATE_VARIANTS = (('prvo cantelli eta 0.8', 'prvo', 0.8, 'cantelli'),
                        *((f'prvo certified eta {eta:g}', 'prvo', eta, 'certified')
                          for eta in (0.8, 0.9, 0.95, 0.99)))
VARIANT_SETS = {'methods': METHOD_VARIANTS, 'certificates': CERTIFICATE_VARIANTS}
# The ablation also under actuation-dominated noise (position, velocity, actuation std).
ACTUATION_DOMINATED = (0.02, 0.02, 0.2)
QUICK_SCENARIOS = ('headon2',)
QUICK_VARIANTS = (METHOD_VARIANTS[1], METHOD_VARIANTS[3])


def with_noise(scenario, noise):
    """Return SCENARIO with every robot's noise replaced by NOISE."""
    robots = tuple(dataclasses.replace(robot, noise=noise) for robot in scenario.robots)
    return dataclasses.replace(scenario, robots=robots)


def belief_covariance(noise):
    """Return the 4x4 belief covariance an odometry reading with NOISE's stds carries."""
    return np.diag([noise.position_std ** 2] * 2 + [noise.velocity_std ** 2] * 2)


def actuation_covariance(noise):
    """Return S_a of a robot whose executed velocity has NOISE's actuation std per axis."""
    return noise.actuation_std ** 2 * np.eye(2)


def snapshot_beliefs(scenario):
    """Return beliefs of the robots SNAPSHOT_DISTANCE from the middle, at full speed to it."""
    beliefs = []
    for robot in scenario.robots:
        heading = (robot.goal - robot.start) / np.linalg.norm(robot.goal - robot.start)
        middle = (robot.goal + robot.start) / 2.0
        beliefs.append(AgentBelief(middle - SNAPSHOT_DISTANCE * heading,
                                   robot.max_speed * heading, belief_covariance(robot.noise),
                                   robot.radius))
    return beliefs


def validation_config(robot, k, with_ego_noise):
    """Return a config whose only constraint is the paper's: mu_f - k sigma_f >= 0 per pair."""
    return PlannerConfig(k=k, max_speed=robot.max_speed, time_horizon=math.inf,
                         receding_gate=False,
                         actuation_cov=actuation_covariance(robot.noise) if with_ego_noise
                         else np.zeros((2, 2)))


def sample_rvo_satisfaction(beliefs, ego, command, actuation_cov, samples, rng):
    """Sample every belief and the ego's actuation noise; return (ego positions, per-pair ok).

    ok[:, j] says whether the deterministic RVO condition f(r, u) >= 0 holds for the pair
    (ego, neighbour j) in each sample, with u = 2 (v_c + eps) - v_i - v_j
    (docs/method.md, sections 2-3).
    """
    states = [rng.multivariate_normal(np.r_[belief.position, belief.velocity],
                                      belief.covariance, size=samples) for belief in beliefs]
    executed = command + rng.multivariate_normal(np.zeros(2), actuation_cov, size=samples)
    satisfied = []
    for other, belief in enumerate(beliefs):
        if other == ego:
            continue
        relative_position = states[ego][:, :2] - states[other][:, :2]
        relative_velocity = 2.0 * executed - states[ego][:, 2:] - states[other][:, 2:]
        combined_radius = beliefs[ego].radius + belief.radius
        satisfied.append(rvo_condition_of(*relative_position.T, *relative_velocity.T,
                                          combined_radius) >= 0.0)
    return states[ego][:, :2], np.stack(satisfied, axis=1)


def validate_snapshot(scenario, k, with_ego_noise, samples, rng):
    """Plan every robot of the snapshot with margin K; sample; return one record per robot."""
    beliefs = snapshot_beliefs(scenario)
    records = []
    for index, robot in enumerate(scenario.robots):
        neighbours = [belief for other, belief in enumerate(beliefs) if other != index]
        v_pref, _ = preferred_velocity(beliefs[index].position, robot.goal, robot.max_speed,
                                       DEFAULTS['approach_time'], 0.0)
        result = plan_velocity(beliefs[index], neighbours, v_pref,
                               validation_config(robot, k, with_ego_noise))
        positions, satisfied = sample_rvo_satisfaction(
            beliefs, index, result.velocity, actuation_covariance(robot.noise), samples, rng)
        records.append({'robot': robot.name, 'command': result.velocity,
                        'feasible': result.feasible, 'achieved_k': result.achieved_k,
                        'positions': positions, 'satisfied': satisfied,
                        'pair_probabilities': satisfied.mean(axis=0),
                        'joint_probability': float(satisfied.all(axis=1).mean())})
    return beliefs, records


def plot_validation(path, scenario, rows, row_titles):
    """Write a figure: one row per (beliefs, records), one column per robot."""
    columns = len(scenario.robots)
    figure, axes_grid = plt.subplots(len(rows), columns, figsize=(4.2 * columns, 4.2 * len(rows)),
                                     squeeze=False)
    colours = robot_colours(columns)
    for row, ((beliefs, records), row_title) in enumerate(zip(rows, row_titles, strict=True)):
        for column, record in enumerate(records):
            axes = axes_grid[row, column]
            joint = record['satisfied'].all(axis=1)
            shown = slice(0, 1500)
            points = record['positions'][shown]
            # The violations first: drawn last, the minority would hide the samples that hold.
            axes.scatter(*points[~joint[shown]].T, s=2, color='black', label='RVO violated')
            axes.scatter(*points[joint[shown]].T, s=2, color='tab:red', alpha=0.6,
                         label='RVO holds')
            for other, belief in enumerate(beliefs):
                axes.add_patch(plt.Circle(belief.position, belief.radius, fill=False,
                                          color=colours[other]))
                axes.arrow(*belief.position, *belief.velocity * 0.5, color=colours[other],
                           width=0.01, alpha=0.5)
            axes.arrow(*beliefs[column].position, *record['command'] * 0.5, color='green',
                       width=0.02, label='chosen velocity')
            pairs = ', '.join(f'{value:.2f}' for value in record['pair_probabilities'])
            axes.set_title(f"{row_title}: {record['robot']}\nP(RVO) per pair {pairs}",
                           fontsize=9)
            axes.set_aspect('equal')
            axes.set_xlim(-3.0, 3.0)
            axes.set_ylim(-3.0, 3.0)
            axes.grid(True, alpha=0.3)
        axes_grid[row, 0].legend(loc='lower left', fontsize=7, markerscale=4)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def closed_loop(scenario, k, seed):
    """Run SCENARIO on the in-process engine, every robot planning PRVO with margin K.

    The planners are the runner's (tracking, goal logic, choice cost), with `k` set. Returns
    (times, positions (T, N, 2)); stops when every robot is within the goal tolerance or at the
    scenario's duration.
    """
    values = [{**planner_values(robot, scenario, 'prvo', None), 'k': float(k)}
              for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    goals = team.world.goals
    times, positions = [], []
    while not team.finished:
        step = team.do_step()
        times.append(step.time)
        positions.append(step.states[:, :2])
        if np.all(np.linalg.norm(positions[-1] - goals, axis=1) <= scenario.goal_tolerance):
            break
    return np.array(times), np.array(positions)


def lateral_deviation(positions, starts, goals):
    """Return each robot's largest distance from its straight start-goal line (N,)."""
    directions = (goals - starts) / np.linalg.norm(goals - starts, axis=1, keepdims=True)
    offsets = positions - starts[None]
    lateral = offsets[..., 0] * directions[None, :, 1] - offsets[..., 1] * directions[None, :, 0]
    return np.abs(lateral).max(axis=0)


def deviation_against_k(scenario, ks, seed, path):
    """Run the closed loop for every k; write the figure; return the table rows."""
    starts = np.array([robot.start for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    radii = np.array([robot.radius for robot in scenario.robots])
    names = [robot.name for robot in scenario.robots]
    figure, axes_row = plt.subplots(1, len(ks), figsize=(4.0 * len(ks), 4.3), squeeze=False)
    rows = []
    for axes, k in zip(axes_row[0], ks, strict=True):
        times, positions = closed_loop(scenario, k, seed)
        run = metrics.run_metrics(times, positions, radii, goals, scenario.goal_tolerance, names)
        contacts = metrics.contact_events(times, positions, radii)
        draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                          labels=names)
        deviation = lateral_deviation(positions, starts, goals)
        axes.set_title(f'k = {k:g} (eta >= {eta_from_k(float(k)):.2f})\nmean max deviation '
                       f'{deviation.mean():.2f} m', fontsize=9)
        rows.append({'k': k, 'deviation': float(deviation.mean()),
                     'min_separation': run['min_separation'], 'collisions': run['collisions'],
                     'makespan': run['makespan'], 'success_rate': run['success_rate']})
    axes_row[0, 0].legend(loc='upper left', fontsize=7)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return rows


def feasible_intervals(accepted, speeds):
    """Return the maximal runs of ACCEPTED speeds as [(low, high), ...]."""
    padded = np.concatenate([[False], np.asarray(accepted, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    return [(float(speeds[first]), float(speeds[last - 1]))
            for first, last in zip(edges[::2], edges[1::2], strict=True)]


def time_scaling_table(noise_std, resolution=4001):
    """Feasible speeds along each agent's current heading: surrogate against enlarged radius.

    Two robots on crossing courses (agent 1 from the left, agent 2 from below), position,
    velocity and actuation stds NOISE_STD. The surrogate is evaluated twice: with position
    uncertainty only (the paper's tables, "for the most probable velocities") and with every
    source. Returns rows (level, agent, surrogate, surrogate_full, inflated).
    """
    positions = np.array([[-2.0, 0.0], [0.25, -2.0]])
    velocities = np.array([[1.0, 0.0], [0.0, 1.0]])
    radius = 0.3
    position_cov = noise_std ** 2 * np.eye(2)
    speeds = np.linspace(0.0, 1.0, resolution)
    rows = []
    for level in CONFIDENCE_LEVELS:
        k = k_from_eta(level)
        enlargement = confidence_ellipse_scale(k)
        for agent, other in ((0, 1), (1, 0)):
            heading = velocities[agent] / np.linalg.norm(velocities[agent])
            relative_position = positions[agent] - positions[other]
            relative_velocity = (2.0 * speeds[:, None] * heading - velocities[agent]
                                 - velocities[other])
            mean = np.concatenate([np.broadcast_to(relative_position, relative_velocity.shape),
                                   relative_velocity], axis=1)
            position_only = np.zeros((4, 4))
            position_only[:2, :2] = 2.0 * position_cov
            cov = position_only.copy()
            cov[2:, 2:] = (4.0 + 2.0) * noise_std ** 2 * np.eye(2)  # 4 S_a + S(v_i) + S(v_j)
            surrogates = []
            for covariance in (position_only, cov):
                expectation, variance = rvo_moments(
                    mean, np.broadcast_to(covariance, (resolution, 4, 4)), 2.0 * radius)
                surrogates.append(expectation - k * np.sqrt(np.maximum(variance, 0.0)) >= 0.0)
            inflated_radius = 2.0 * radius + enlargement * math.sqrt(
                float(np.linalg.eigvalsh(cov[:2, :2]).max()))
            inflated = rvo_condition_of(*relative_position, *relative_velocity.T,
                                        inflated_radius) >= 0.0
            rows.append({'level': level, 'k': k, 'agent': agent + 1,
                         'surrogate': feasible_intervals(surrogates[0], speeds),
                         'surrogate_full': feasible_intervals(surrogates[1], speeds),
                         'inflated': feasible_intervals(inflated, speeds)})
    return rows


def random_encounter(rng):
    """Return (ego, neighbours, v_pref) of a random encounter with 1-3 noisy neighbours."""
    ego, neighbours = encounters.random_encounter(rng)
    goal_angle = rng.uniform(0.0, 2.0 * math.pi)
    return ego, neighbours, np.array([math.cos(goal_angle), math.sin(goal_angle)])


def taylor_against_exact(count, seed):
    """Plan COUNT random encounters with both ray solvers; return the error statistics."""
    rng = np.random.default_rng(seed)
    differences, violations, times = [], 0, {'exact': [], 'taylor': []}
    for _ in range(count):
        ego, neighbours, v_pref = random_encounter(rng)
        k = float(rng.choice([1.0, 2.0]))
        results = {}
        for method in ('exact', 'taylor'):
            config = PlannerConfig(k=k, method=method, actuation_cov=0.05 ** 2 * np.eye(2))
            started = time.perf_counter()
            results[method] = plan_velocity(ego, neighbours, v_pref, config)
            times[method].append((time.perf_counter() - started) * 1e3)
        differences.append(float(np.linalg.norm(results['exact'].velocity
                                                - results['taylor'].velocity)))
        # achieved_k is evaluated with the exact moments: below k, Taylor's choice breaks it.
        if results['taylor'].feasible and results['taylor'].achieved_k < k - 1e-6:
            violations += 1
    differences = np.array(differences)
    return {'encounters': count, 'median': float(np.median(differences)),
            'p95': float(np.percentile(differences, 95)), 'max': float(differences.max()),
            'identical': float(np.mean(differences < 1e-9)),
            'taylor_violations': violations / count,
            'exact_ms': float(np.median(times['exact'])),
            'taylor_ms': float(np.median(times['taylor']))}


def scenario_with_certificate(scenario_path, certificate, out_dir):
    """Return the path of a copy of SCENARIO_PATH whose planners certify with CERTIFICATE.

    The copy, in OUT_DIR, keeps the file's name; the runner's command line has no option for
    the bound, a scenario's planner block does.
    """
    document = yaml.safe_load(pathlib.Path(scenario_path).read_text())
    document['planner'] = {**(document.get('planner') or {}), 'certificate': certificate}
    path = out_dir / f'{scenario_path.stem}.yaml'
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return path


def run_method_table(out_dir, scenarios, variants, seeds, timeout):
    """Run the scenario runner for every scenario and variant; return the table rows."""
    rows = []
    for scenario_name in scenarios:
        for label, method, eta, certificate in variants:
            run_dir = out_dir / 'runs' / scenario_name / label.replace(' ', '_')
            scenario_path = find_scenario(scenario_name)
            if certificate is not None:
                scenario_path = scenario_with_certificate(scenario_path, certificate,
                                                          out_dir / 'scenarios' / certificate)
            command = [sys.executable, '-m', 'prvo_sim.run_scenario', str(scenario_path),
                       '--out', str(run_dir), '--method', method, '--seeds', str(seeds),
                       '--engine', 'inprocess', '--quiet', '--timeout', str(timeout),
                       # The tables need the metrics; a GIF and a bag per run would triple the
                       # cost of hundreds of runs.
                       '--no-animation', '--no-bag']
            if eta is not None:
                command += ['--eta', str(eta)]
            started = time.monotonic()
            completed = subprocess.run(command, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.PIPE, text=True)
            if completed.returncode == 2:
                raise RuntimeError(f'runner rejected {command}: {completed.stderr.strip()}')
            folders = [run_dir] if seeds == 1 else sorted(run_dir.glob('seed_*'))
            runs = [json.loads((folder / 'metrics.json').read_text()) for folder in folders
                    if (folder / 'metrics.json').exists()]
            summary = metrics.aggregate(runs, ('collisions', 'success_rate',
                                               'mean_time_to_goal', 'min_separation'))
            rows.append({'scenario': scenario_name, 'method': label, 'runs': len(runs),
                         'failed': sum(not Ending(run['ending']).completed for run in runs),
                         'collisions_total': int(sum(run['collisions'] for run in runs)),
                         'summary': summary})
            print(f'  {scenario_name:<10} {label:<20} {len(runs)} runs in '
                  f'{time.monotonic() - started:.0f} s', flush=True)
    return rows


def _stat(summary, key, digits=2):
    stats = summary[key]
    if stats['n'] == 0:
        return 'n/a'
    return f"{stats['mean']:.{digits}f} ± {stats['std']:.{digits}f}"


def _intervals_text(intervals):
    return ' ∪ '.join(f'[{low:.2f}, {high:.2f}]' for low, high in intervals) or 'empty'


def methods_lines(results):
    """Return the Markdown lines of item 5's table."""
    if not results['methods']:
        return ['Skipped (`--skip-runs`).']
    lines = [f"{results['seeds']} seed(s) per cell, through the scenario runner's "
             'in-process engine (the trajectories of a ROS lockstep run; mean ± std over '
             'seeds):', '',
             '| scenario | method | runs (failed) | collisions (total) | success rate | '
             'mean time to goal [s] | min separation [m] |', '|---|---|---|---|---|---|---|']
    for row in results['methods']:
        summary = row['summary']
        lines.append(f"| {row['scenario']} | {row['method']} | {row['runs']} "
                     f"({row['failed']}) | {_stat(summary, 'collisions')} "
                     f"({row['collisions_total']}) | {_stat(summary, 'success_rate')} | "
                     f"{_stat(summary, 'mean_time_to_goal', 1)} | "
                     f"{_stat(summary, 'min_separation')} |")
    return lines


def write_methods_report(path, results):
    """Write the Markdown report of the methods table alone (--methods-only)."""
    lines = ['# PRVO: methods over the shipped scenarios', '',
             f"Generated by `python -m prvo_sim.bench.experiments --methods-only --variants "
             f"{results['variants']}`; {results['wall_time']:.0f} s of wall time.", '',
             *methods_lines(results), '']
    path.write_text('\n'.join(lines))


def write_report(path, results):
    """Write the Markdown report of every item in RESULTS."""
    lines = ["# PRVO: the paper's section 6, reproduced", '',
             f"Generated by `python -m prvo_sim.bench.experiments` ({results['mode']}); "
             f"{results['wall_time']:.0f} s of wall time.", '']
    lines += ['## 1. Cantelli validation (paper figures 2-3)', '',
              f'`paper3`, the robots {SNAPSHOT_DISTANCE:g} m from the meeting point at full '
              'speed. Each robot plans with only the surrogate `mu_f - k sigma_f >= 0` per pair; '
              'the beliefs and its actuation noise are then sampled at the chosen velocity, '
              f"{results['samples']} samples. Measured `P(f >= 0)` per pair against Cantelli's "
              'bound `k^2 / (1 + k^2)`:', '',
              '| k | bound | robot | feasible | P per pair | min P | joint P |',
              '|---|---|---|---|---|---|---|']
    for k, records in results['validation'].items():
        for record in records:
            pairs = ', '.join(f'{value:.3f}' for value in record['pair_probabilities'])
            lines.append(f"| {k:g} | {eta_from_k(float(k)):.2f} | {record['robot']} | "
                         f"{record['feasible']} | {pairs} | "
                         f"{min(record['pair_probabilities']):.3f} | "
                         f"{record['joint_probability']:.3f} |")
    lines += ['', '![Cantelli validation](cantelli_validation.png)', '',
              '## 2. Deviation against k (paper figure 4)', '',
              "`paper3` on the in-process engine (the runner's planners with margin k: "
              'tracked noisy odometry, actuation noise on execution; same seed for every k):',
              '',
              '| k | bound eta | mean max lateral deviation [m] | min separation [m] | '
              'collisions | makespan [s] |', '|---|---|---|---|---|---|']
    for row in results['deviation']:
        makespan = 'n/a' if row['makespan'] is None else f"{row['makespan']:.1f}"
        lines.append(f"| {row['k']:g} | {row['k'] ** 2 / (1 + row['k'] ** 2):.2f} | "
                     f"{row['deviation']:.3f} | {row['min_separation']:.3f} | "
                     f"{row['collisions']} | {makespan} |")
    lines += ['', '![Deviation against k](deviation_against_k.png)', '',
              '## 3. Ego-noise ablation (paper figure 5)', '',
              'Same snapshot, k = 1 (bound 0.5), actuation noise always present when sampling; '
              "planned without (`S_a = 0`) and with the robot's actuation noise; with paper3's "
              'noise (stds 0.08) and with actuation-dominated noise (position and velocity '
              f'stds {ACTUATION_DOMINATED[0]:g}, actuation {ACTUATION_DOMINATED[2]:g}). The '
              'figure shows the first:', '',
              '| planned with | robot | P per pair | min P |', '|---|---|---|---|']
    for label, records in results['ablation'].items():
        for record in records:
            pairs = ', '.join(f'{value:.3f}' for value in record['pair_probabilities'])
            lines.append(f"| {label} | {record['robot']} | {pairs} | "
                         f"{min(record['pair_probabilities']):.3f} |")
    lines += ['', '![Ego-noise ablation](ego_noise_ablation.png)', '',
              '## 4. Time-scaling intervals against radius enlargement (paper tables 1-2)', '',
              'Two robots on crossing courses, all stds '
              f"{results['table_noise']:g}; feasible speeds `s` in [0, 1] m/s along each "
              "agent's current heading (surrogate with `k = sqrt(eta / (1 - eta))`; enlarged "
              'radius `R + sqrt(-2 ln(1 - eta)) sqrt(lambda_max(S_rr))` on the means):', '',
              '| confidence | agent | surrogate, position uncertainty | radius enlargement | '
              'surrogate, all uncertainty |', '|---|---|---|---|---|']
    for row in results['intervals']:
        lines.append(f"| {row['level']:.0%} | {row['agent']} | "
                     f"{_intervals_text(row['surrogate'])} | "
                     f"{_intervals_text(row['inflated'])} | "
                     f"{_intervals_text(row['surrogate_full'])} |")
    lines += ['', '## 5. Methods over the shipped scenarios', '', *methods_lines(results)]
    taylor = results['taylor']
    lines += ['', '### Exact against Taylor ray solver', '',
              f"{taylor['encounters']} random encounters (1-3 noisy neighbours, k in {{1, 2}}): "
              f"|v_exact - v_taylor| median {taylor['median']:.4f}, p95 {taylor['p95']:.4f}, "
              f"max {taylor['max']:.4f} m/s; identical choice in {taylor['identical']:.0%}; "
              f"Taylor's choice breaks the exact surrogate in {taylor['taylor_violations']:.1%}"
              f" of encounters; median plan time exact {taylor['exact_ms']:.2f} ms, Taylor "
              f"{taylor['taylor_ms']:.2f} ms.", '']
    path.write_text('\n'.join(lines))


def methods_table(options, out_dir):
    """Run item 5's table as OPTIONS ask; return {'seeds', 'variants', 'methods': rows}."""
    seeds = 1 if options.quick else options.seeds
    variants = QUICK_VARIANTS if options.quick else VARIANT_SETS[options.variants]
    return {'seeds': seeds, 'variants': options.variants,
            'methods': run_method_table(out_dir, QUICK_SCENARIOS if options.quick
                                        else options.scenarios, variants, seeds,
                                        timeout=300.0)}


def build_parser():
    """Return the command-line parser of the experiments."""
    parser = argparse.ArgumentParser(prog='experiments', description=__doc__.split('\n')[0])
    parser.add_argument('--out', type=pathlib.Path, default=pathlib.Path('results/paper'),
                        help='output folder (default: results/paper)')
    parser.add_argument('--seeds', type=int, default=10, help='seeds per scenario and method')
    parser.add_argument('--quick', action='store_true',
                        help='smoke test: 1 seed, headon2 with prvo and rvo, fewer samples')
    parser.add_argument('--skip-runs', action='store_true', help='leave out the ROS runs')
    parser.add_argument('--variants', choices=tuple(VARIANT_SETS), default='methods',
                        help='rows of the methods table: the methods (default) or the '
                             "certificates (Cantelli's bound at eta 0.8, the certified bound "
                             'at 0.8, 0.9, 0.95 and 0.99)')
    parser.add_argument('--scenarios', nargs='+', choices=SCENARIOS, default=list(SCENARIOS),
                        help='shipped scenarios of the methods table (default: all)')
    parser.add_argument('--methods-only', action='store_true',
                        help='run only the methods table (item 5, without the Taylor check)')
    parser.add_argument('--seed', type=int, default=5, help='seed of the ROS-free parts')
    return parser


def main(argv=None):
    """Run the experiments; return the exit code."""
    options = build_parser().parse_args(argv)
    if options.seeds < 1:
        print(f'experiments: error: --seeds: {options.seeds} is not a positive count',
              file=sys.stderr)
        return 2
    if options.methods_only and options.skip_runs:
        print('experiments: error: --methods-only and --skip-runs leave nothing to do',
              file=sys.stderr)
        return 2
    started = time.monotonic()
    out_dir = options.out
    out_dir.mkdir(parents=True, exist_ok=True)
    if options.methods_only:
        results = methods_table(options, out_dir)
        results['wall_time'] = time.monotonic() - started
        (out_dir / 'methods.json').write_text(json.dumps(results, indent=1) + '\n')
        write_methods_report(out_dir / 'report.md', results)
        print(f"report: {out_dir / 'report.md'} ({results['wall_time']:.0f} s)")
        return 0
    scenario = load_scenario(find_scenario('paper3'))
    samples = 4000 if options.quick else 20000
    rng = np.random.default_rng(options.seed)
    results = {'mode': 'quick' if options.quick else 'full', 'samples': samples,
               'table_noise': scenario.robots[0].noise.position_std}

    print('1. Cantelli validation', flush=True)
    validation_rows = [validate_snapshot(scenario, k, True, samples, rng) for k in VALIDATION_KS]
    results['validation'] = {k: records for k, (_, records)
                             in zip(VALIDATION_KS, validation_rows, strict=True)}
    plot_validation(out_dir / 'cantelli_validation.png', scenario, validation_rows,
                    [f'k = {k:g}' for k in VALIDATION_KS])

    print('2. Deviation against k', flush=True)
    ks = (1.0, 2.0) if options.quick else DEVIATION_KS
    results['deviation'] = deviation_against_k(scenario, ks, options.seed,
                                               out_dir / 'deviation_against_k.png')

    print('3. Ego-noise ablation', flush=True)
    results['ablation'] = {}
    for noise_label, noisy_scenario in (('paper3 noise', scenario), (
            'actuation-dominated noise', with_noise(scenario, NoiseSpec(*ACTUATION_DOMINATED)))):
        ablation_rows = [validate_snapshot(noisy_scenario, 1.0, with_ego, samples, rng)
                         for with_ego in (False, True)]
        labels = (f'{noise_label}, without S_a', f'{noise_label}, with S_a')
        results['ablation'].update({label: records for label, (_, records)
                                    in zip(labels, ablation_rows, strict=True)})
        if noisy_scenario is scenario:
            plot_validation(out_dir / 'ego_noise_ablation.png', scenario, ablation_rows, labels)

    print('4. Time-scaling intervals', flush=True)
    results['intervals'] = time_scaling_table(results['table_noise'])

    print('5. Methods over the scenarios, and exact against Taylor', flush=True)
    results.update({} if options.skip_runs else methods_table(options, out_dir))
    results.setdefault('methods', [])
    results['taylor'] = taylor_against_exact(100 if options.quick else 1000, options.seed)

    results['wall_time'] = time.monotonic() - started
    write_report(out_dir / 'report.md', results)
    print(f"report: {out_dir / 'report.md'} ({results['wall_time']:.0f} s)")
    return 0


if __name__ == '__main__':
    sys.exit(main())
