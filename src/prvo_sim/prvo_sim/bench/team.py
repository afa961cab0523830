"""Team benchmark: what a team of 4, 8 or 16 robots costs, in lockstep and in realtime.

    python -m prvo_sim.bench.team [--robots 4 8 16] [--json PATH] [--realtime-seconds S]
                                  [--out DIR]

For each team size N it writes a circle scenario like circle8 (N robots swapping antipodal
points under noise), runs it with the scenario runner's own code in lockstep to completion, then
in realtime at 10 Hz for S seconds of wall time or to completion, and prints one Markdown table
row per N: lockstep wall time (process start to completion), simulated time, lockstep steps per
wall second of the stepping phase, arrivals and collisions, each planner's and the simulator's
CPU (percent of one core and ms per step, over the stepping phase, from /proc/<pid>/stat) and
peak RSS (VmHWM, read just before shutdown), and the realtime deadline-miss rate (misses /
(steps x robots), from the simulator's status). Run outputs and child logs go to DIR
(default results/bench_team).

Exit codes: 0 every run completed, 1 a run failed, 2 bad input, 128 + signal number when
interrupted.
"""

import argparse
import json
import math
import os
import pathlib
import shlex
import sys
import time

import yaml

from prvo_sim import run_scenario
from prvo_sim.scenario import load_scenario

DEFAULT_TEAM_SIZES = (4, 8, 16)
DEFAULT_REALTIME_SECONDS = 20.0
# circle8's settings, shared by every team size.
SEED = 7
DT = 0.1
GOAL_TOLERANCE = 0.2
NOISE_STD = 0.05
ROBOT_RADIUS = 0.3
MAX_SPEED = 1.0
ETA = 0.8
CERTIFICATE = 'cantelli'
# The peers' (RVO2's, navground's ORCA) horizon against robots [s], prvo's default until it
# became 2 s, fixed so that the issues' reference makespans stay the same: at 2 s RVO2 jams at
# doorway8's door (4 of 8 through, 555 contacts; docs/results.md, section 3.5).
PEER_TIME_HORIZON = 5.0
CIRCLE8_RADIUS = 4.0
# Arc between neighbours on the start circle beyond which it grows: 16 robots get 6 m.
MIN_ARC_SPACING = 2.35
# Simulated seconds allowed per metre of circle diameter at MAX_SPEED: circle8's 60 s for 8 m.
DURATION_PER_METRE = 7.5
REALTIME_RATE = 10.0  # Hz
CLOCK_TICKS_PER_SECOND = os.sysconf('SC_CLK_TCK')
KIB_PER_MIB = 1024.0


def circle_radius(team_size):
    """Return the start circle's radius [m]: circle8's 4 m, grown for a larger team.

    Beyond 8 robots the radius keeps MIN_ARC_SPACING of arc between neighbours, rounded up to
    half a metre.
    """
    spaced = team_size * MIN_ARC_SPACING / (2.0 * math.pi)
    return max(CIRCLE8_RADIUS, math.ceil(2.0 * spaced) / 2.0)


def circle_document(team_size, duration=None, radius=None):
    """Return the scenario document of TEAM_SIZE robots swapping antipodal points on a circle.

    Robot i starts at angle 2 pi i / TEAM_SIZE and drives to the opposite point. DURATION
    defaults to DURATION_PER_METRE per metre of diameter, RADIUS [m] to `circle_radius`.
    """
    if radius is None:
        radius = circle_radius(team_size)
    if duration is None:
        duration = DURATION_PER_METRE * 2.0 * radius / MAX_SPEED
    robots = []
    for index in range(team_size):
        angle = 2.0 * math.pi * index / team_size
        # Rounded like the shipped files; adding 0.0 turns -0.0 into 0.0.
        start = [round(radius * math.cos(angle), 4) + 0.0,
                 round(radius * math.sin(angle), 4) + 0.0]
        robots.append({'name': f'robot_{index}', 'start': start,
                       'goal': [-start[0] + 0.0, -start[1] + 0.0],
                       'radius': ROBOT_RADIUS, 'max_speed': MAX_SPEED})
    return {
        'name': f'bench_circle{team_size}',
        'description': f'{team_size} robots on a {radius:g} m circle swap to antipodal points '
                       'under sensing and actuation noise (team benchmark).',
        'seed': SEED, 'dt': DT, 'duration': float(duration), 'goal_tolerance': GOAL_TOLERANCE,
        'noise': {'position_std': NOISE_STD, 'velocity_std': NOISE_STD,
                  'actuation_std': NOISE_STD},
        'planner': {'eta': ETA, 'certificate': CERTIFICATE},
        'robots': robots,
    }


def write_scenario(document, path):
    """Write DOCUMENT as YAML to PATH and return it loaded (and so validated) as a Scenario."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return load_scenario(path)


def parse_cpu_ticks(stat_text):
    """Return utime + stime [clock ticks] from the text of a /proc/<pid>/stat file."""
    # The command name, in parentheses, may itself hold spaces and parentheses.
    fields = stat_text.rpartition(')')[2].split()
    # fields[0] is field 3 (state) of proc(5); utime and stime are fields 14 and 15.
    return int(fields[11]) + int(fields[12])


def parse_peak_rss_kib(status_text):
    """Return VmHWM [KiB] from the text of a /proc/<pid>/status file, or None if absent."""
    for line in status_text.splitlines():
        if line.startswith('VmHWM:'):
            return int(line.split()[1])
    return None


def cpu_seconds(pid):
    """Return the CPU time (user + system, all threads) process PID has used, or None if gone."""
    try:
        return parse_cpu_ticks(pathlib.Path(f'/proc/{pid}/stat').read_text()) / (
            CLOCK_TICKS_PER_SECOND)
    except (OSError, IndexError, ValueError):
        return None


def peak_rss_kib(pid):
    """Return the peak resident set size [KiB] of process PID, or None if gone."""
    try:
        return parse_peak_rss_kib(pathlib.Path(f'/proc/{pid}/status').read_text())
    except OSError:
        return None


class TeamMonitor:
    """Measures one run from inside the runner (see run_scenario.run_once's MONITOR).

    It times the simulator's steps as their status arrives and reads every child's CPU time at
    the first step and when the run ends, and its peak RSS when the run ends.
    """

    def __init__(self):
        self.pids = {}
        self.sim_status = None  # world_messages.SimStatus
        self.first_step = None  # (wall time, step, {label: CPU seconds})
        self.last_step = None  # (wall time, step)
        self.ended = None  # (wall time, {label: CPU seconds}, {label: peak RSS KiB})

    def started(self, children, recorder):
        """Note the children's pids and listen to the simulator's status."""
        self.pids = {process.label: process.pid for process in children.processes}
        recorder.diagnostics_listeners.append(self._on_diagnostics)

    def _on_diagnostics(self, msg):
        from prvo_sim.world_messages import sim_status_of

        now = time.monotonic()
        for status in msg.status:
            sim_status = sim_status_of(status)
            if sim_status is None:
                continue
            self.sim_status = sim_status
            step = sim_status.step
            # Before and after stepping the simulator repeats its status: only new steps count.
            if step == 0 or (self.last_step is not None and step == self.last_step[1]):
                continue
            if self.first_step is None:
                self.first_step = (now, step, self._cpu_seconds())
            self.last_step = (now, step)

    def ending(self, children, recorder):
        """Read every child's CPU time and peak RSS before the runner stops them."""
        self.ended = (time.monotonic(), self._cpu_seconds(),
                      {label: peak_rss_kib(pid) for label, pid in self.pids.items()})

    def _cpu_seconds(self):
        return {label: cpu_seconds(pid) for label, pid in self.pids.items()}

    def stepping(self):
        """Return (steps, wall seconds) from the first to the last step seen, or None."""
        if self.first_step is None or self.last_step[1] == self.first_step[1]:
            return None
        return self.last_step[1] - self.first_step[1], self.last_step[0] - self.first_step[0]

    def process_use(self, label):
        """Return (CPU fraction of one core, CPU ms per step, peak RSS MiB) of child LABEL.

        CPU is counted from the first step to the end of the run, so that the interpreter's
        start-up is left out; a value is None when it could not be read.
        """
        if self.ended is None:
            return None, None, None
        ended_at, cpu_at_end, peak_rss = self.ended
        rss_mib = peak_rss[label] / KIB_PER_MIB if peak_rss[label] is not None else None
        if self.first_step is None:
            return None, None, rss_mib
        first_at, first_step, cpu_at_first = self.first_step
        if cpu_at_end[label] is None or cpu_at_first[label] is None:
            return None, None, rss_mib
        used = cpu_at_end[label] - cpu_at_first[label]
        steps = self.last_step[1] - first_step
        return (used / (ended_at - first_at) if ended_at > first_at else None,
                1000.0 * used / steps if steps else None, rss_mib)


def run_options(mode):
    """Return the runner options of a benchmark run in MODE (lockstep or realtime)."""
    sim_command = None
    if mode == 'realtime':
        # A ROS-args block of its own ahead of the one the runner appends.
        sim_command = shlex.join([
            *run_scenario.package_command('prvo_sim', 'sim', 'prvo_sim.sim_node'),
            '--ros-args', '-p', f'rate:={REALTIME_RATE!r}', '--'])
    # The team is measured: no bag (whose markers the planners would build), no animation.
    return argparse.Namespace(method='prvo', mode=mode, timeout=None, quiet=False,
                              sim_command=sim_command, planner_command=None, bag=False,
                              animation=False)


def run_measured(scenario, mode, out_dir, domain_id):
    """Run SCENARIO once in MODE; return (RunResult, monitor, wall s to the end)."""
    spec = run_scenario.RunSpec(run_options(mode), scenario, ETA, scenario.seed, out_dir)
    monitor = TeamMonitor()
    started_at = time.monotonic()
    result = run_scenario.run_once(spec, domain_id, monitor)
    wall_time = monitor.ended[0] - started_at if monitor.ended is not None else None
    return result, monitor, wall_time


def _mean(values):
    values = [value for value in values if value is not None]
    return sum(values) / len(values) if values else None


def _max(values):
    values = [value for value in values if value is not None]
    return max(values) if values else None


def _percent(fraction):
    return 100.0 * fraction if fraction is not None else None


def _rounded(value, digits):
    return round(value, digits) if value is not None else None


def lockstep_result(scenario, run, monitor, wall_time):
    """Return the lockstep fields of a result row of RUN (a RunResult)."""
    run_metrics = run.metrics
    planner_labels = [f'planner_{robot.name}' for robot in scenario.robots]
    planners = [monitor.process_use(label) for label in planner_labels]
    sim_cpu, sim_ms_per_step, sim_rss = monitor.process_use('sim')
    stepping = monitor.stepping()
    result = {
        'lockstep_wall_s': _rounded(wall_time, 2),
        'sim_s': run_metrics['sim_time'],
        'lockstep_steps': stepping[0] if stepping else None,
        'lockstep_stepping_wall_s': _rounded(stepping[1], 2) if stepping else None,
        'steps_per_s': _rounded(stepping[0] / stepping[1], 2) if stepping else None,
        'all_arrived': run_metrics['success_rate'] == 1.0,
        'collisions': run_metrics['collisions'],
        'planner_cpu_pct_mean': _rounded(_percent(_mean(cpu for cpu, _, _ in planners)), 1),
        'planner_cpu_pct_max': _rounded(_percent(_max(cpu for cpu, _, _ in planners)), 1),
        'planner_cpu_ms_per_step': _rounded(_mean(ms for _, ms, _ in planners), 2),
        'planner_plan_ms_median': run_metrics['planner_ms']['median'],
        'planner_rss_mib_mean': _rounded(_mean(rss for _, _, rss in planners), 1),
        'planner_rss_mib_max': _rounded(_max(rss for _, _, rss in planners), 1),
        'sim_cpu_pct': _rounded(_percent(sim_cpu), 1),
        'sim_cpu_ms_per_step': _rounded(sim_ms_per_step, 2),
        'sim_rss_mib': _rounded(sim_rss, 1),
    }
    if not run.ending.completed:
        result['lockstep_failure'] = run.failure
    return result


def deadline_miss_rate(deadline_misses, steps, team_size):
    """Return the fraction of robot-steps whose command missed its deadline, or None."""
    if not steps:
        return None
    return deadline_misses / (steps * team_size)


def realtime_result(scenario, run, monitor):
    """Return the realtime fields of a result row of RUN (a RunResult)."""
    run_metrics = run.metrics
    steps = monitor.sim_status.step if monitor.sim_status is not None else 0
    misses = monitor.sim_status.deadline_misses if monitor.sim_status is not None else 0
    planner_cpu = [monitor.process_use(f'planner_{robot.name}')[0] for robot in scenario.robots]
    rate = deadline_miss_rate(misses, steps, len(scenario.robots))
    result = {
        'realtime_steps': steps,
        'realtime_deadline_misses': misses,
        'realtime_miss_rate_pct': _rounded(_percent(rate), 2),
        'realtime_all_arrived': run_metrics['success_rate'] == 1.0,
        'realtime_collisions': run_metrics['collisions'],
        'realtime_planner_cpu_pct_mean': _rounded(_percent(_mean(planner_cpu)), 1),
    }
    if not run.ending.completed:
        result['realtime_failure'] = run.failure
    return result


TABLE_COLUMNS = (
    ('robots', 'robots', '{}'),
    ('lockstep wall s', 'lockstep_wall_s', '{:.1f}'),
    ('sim s', 'sim_s', '{:.1f}'),
    ('steps/s', 'steps_per_s', '{:.2f}'),
    ('all arrived', 'all_arrived', '{}'),
    ('collisions', 'collisions', '{}'),
    ('planner CPU % mean/max', ('planner_cpu_pct_mean', 'planner_cpu_pct_max'), '{:.1f}'),
    ('planner CPU ms/step', 'planner_cpu_ms_per_step', '{:.1f}'),
    ('planner RSS MiB mean/max', ('planner_rss_mib_mean', 'planner_rss_mib_max'), '{:.0f}'),
    ('sim CPU %', 'sim_cpu_pct', '{:.1f}'),
    ('sim RSS MiB', 'sim_rss_mib', '{:.0f}'),
    ('realtime miss %', 'realtime_miss_rate_pct', '{:.2f}'),
)


def _cell_value(value, form):
    if value is None:
        return 'n/a'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    return form.format(value)


def _cell(result, keys, form):
    keys = keys if isinstance(keys, tuple) else (keys,)
    return '/'.join(_cell_value(result.get(key), form) for key in keys)


def format_table(results):
    """Return RESULTS as a Markdown table, one row per team size."""
    header = [title for title, _, _ in TABLE_COLUMNS]
    rows = [[_cell(result, keys, form) for _, keys, form in TABLE_COLUMNS]
            for result in results]
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join('---' for _ in header) + '|']
    lines += ['| ' + ' | '.join(row) + ' |' for row in rows]
    return '\n'.join(lines)


def bench_team_size(team_size, options, domain_id):
    """Run TEAM_SIZE robots in lockstep then realtime; return (result row, interrupting signal)."""
    folder = options.out / f'circle{team_size}'
    document = circle_document(team_size)
    scenario = write_scenario(document, folder / f'{document["name"]}.yaml')
    result = {'robots': team_size, 'circle_radius_m': circle_radius(team_size)}
    run, monitor, wall_time = run_measured(scenario, 'lockstep', folder / 'lockstep', domain_id)
    print(f'{team_size} robots, lockstep: {run_scenario.outcome(run.metrics)}', flush=True)
    result.update(lockstep_result(scenario, run, monitor, wall_time))
    if run.interrupted is not None:
        return result, run.interrupted
    # Ends after the realtime seconds at 10 Hz, unless every robot arrived before.
    realtime_document = circle_document(
        team_size, duration=min(document['duration'], options.realtime_seconds))
    realtime_scenario = write_scenario(
        realtime_document, folder / f'{document["name"]}_realtime.yaml')
    run, monitor, _ = run_measured(realtime_scenario, 'realtime', folder / 'realtime', domain_id)
    print(f'{team_size} robots, realtime {REALTIME_RATE:g} Hz: '
          f'{run_scenario.outcome(run.metrics)}', flush=True)
    result.update(realtime_result(realtime_scenario, run, monitor))
    return result, run.interrupted


def build_parser():
    """Return the command-line parser of the team benchmark."""
    parser = run_scenario._ArgumentParser(
        prog='python -m prvo_sim.bench.team',
        description='Benchmark teams of robots: CPU, RSS, lockstep speed, realtime misses.')
    parser.add_argument('--robots', type=int, nargs='+', default=list(DEFAULT_TEAM_SIZES),
                        help='team sizes (default: 4 8 16)')
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"results": [...]} to this file')
    parser.add_argument('--realtime-seconds', type=float, default=DEFAULT_REALTIME_SECONDS,
                        help='wall seconds of the realtime run, unless the team arrives first'
                             f' (default: {DEFAULT_REALTIME_SECONDS:g})')
    parser.add_argument('--out', type=pathlib.Path, default=pathlib.Path('results/bench_team'),
                        help='folder of the scenarios, run outputs and child logs '
                             '(default: results/bench_team)')
    return parser


def parse_arguments(argv):
    """Parse and check ARGV; raise run_scenario.UsageError on bad input."""
    options = build_parser().parse_args(argv)
    for team_size in options.robots:
        if team_size < 2:
            raise run_scenario.UsageError(f'--robots: {team_size} is not a team (at least 2)')
    if not options.realtime_seconds > 0.0:
        raise run_scenario.UsageError(
            f'--realtime-seconds: {options.realtime_seconds} is not a positive time')
    run_scenario.check_writable(options.out)
    if options.json is not None:
        run_scenario.check_writable(options.json.parent)
    return options


def domain_with_strangers(domain_id):
    """Return why DOMAIN_ID is in use by processes the benchmark did not start, else None."""
    return run_scenario.foreign_participants(domain_id, [])


def run(options):
    """Benchmark every team size; print the table; return the exit code."""
    results = []
    interrupted = None
    with run_scenario.claimed_domain(None, vet=domain_with_strangers) as domain_id:
        for team_size in options.robots:
            result, interrupted = bench_team_size(team_size, options, domain_id)
            results.append(result)
            if interrupted is not None:
                break
    print(format_table(results))
    if options.json is not None:
        options.json.parent.mkdir(parents=True, exist_ok=True)
        with open(options.json, 'w') as json_file:
            json.dump({'results': results}, json_file, indent=2)
            json_file.write('\n')
    if interrupted is not None:
        return 128 + interrupted
    failed = any('lockstep_failure' in result or 'realtime_failure' in result
                 for result in results)
    return 1 if failed else 0


def main(argv=None):
    """Run the team benchmark's command line; return the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    try:
        options = parse_arguments(argv)
    except run_scenario.UsageError as error:
        print(f'prvo_sim.bench.team: error: {error}', file=sys.stderr)
        return 2
    return run_scenario.run_interruptibly('prvo_sim.bench.team', lambda: run(options))

if __name__ == '__main__':
    sys.exit(main())
