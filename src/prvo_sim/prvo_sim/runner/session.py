"""One run: the planners, then the simulator once the recorder hears every planner, recorded.

The order makes a run complete from t_0 however fast the team is: the recorder matches every
planner's cmd_vel and diagnostics publisher before the simulator starts, and the simulator is
told to wait (its `observers` parameter) until the recorder is subscribed to every robot's
ground truth and to /diagnostics before it takes its first step.
"""

import math
import pathlib
import shlex
import sys
import time

import numpy as np

from prvo_planner.parameters import DEFAULTS as PLANNER_DEFAULTS
from prvo_sim.runner.outputs import Ending, RunResult, write_outputs
from prvo_sim.runner.processes import (
    INTERRUPTS,
    Children,
    RunInterruptedError,
    child_environment,
    package_command,
)

METHODS = ('prvo', 'rvo', 'inflate', 'prvo-no-ego', 'none')
# The planner's `model` parameter for each method; prvo-no-ego is PRVO planned with S_a = 0,
# none avoids nobody (the reference that shows what avoidance adds).
MODEL_OF_METHOD = {'prvo': 'prvo', 'rvo': 'rvo', 'inflate': 'inflate', 'prvo-no-ego': 'prvo',
                   'none': 'none'}
ENGINES = ('ros', 'inprocess')
DEFAULT_ETA = PLANNER_DEFAULTS['eta']
SIM_NODE = 'prvo_sim'
PLANNER_NODE = 'planner'
STAND_IN_NODE = 'nav2_stand_in'
PATH_STAND_IN_NODE = 'planner_server_stand_in'
# Wall seconds a lockstep run waits for any one answer: for a planner's command (the simulator's
# step_timeout and startup_timeout), for a neighbour's odometry or first announcement (the
# planners' sync_timeout and neighbor_timeout, a little less, so that a plan is still in time).
# Every step is waited for in full however loaded the machine (under a load of 20 on 2 cores a
# 2 s wait ran out at the first step and parted the run from the in-process one): only a
# stalled team reaches the bound, which keeps a run that lost a message going.
LOCKSTEP_PATIENCE = 30.0
STEP_TIMEOUT = LOCKSTEP_PATIENCE
STARTUP_LIMIT = 60.0  # wall seconds for each start-up stage before the run counts as failed
SETTLE_TIME = 1.0  # sim seconds every robot must stay at its goal before the run ends
# Sim seconds below which two times count as equal: the engines' clocks (stamps in ns, sums of
# steps) differ by rounding, and the end of a run must not.
TIME_EPSILON = 1e-6
PROGRESS_PERIOD = 0.5
# Wall seconds for messages in flight when a run ends to arrive (a wait that ends as soon as
# the recording is complete): longer than a planner may take to answer a step (STEP_TIMEOUT),
# since the step the run ends at must have its answers.
RECORDING_GRACE = STEP_TIMEOUT + 1.0
GRAPH_CHECK_PERIOD = 1.0  # wall seconds between looks for intruders during a run
# Planner waits in lockstep [s], for same-stamp odometry and for every listed neighbour's first
# messages: as long as the simulator waits for the plan, less a margin to plan. A neighbour
# counts as gone only after as long: in lockstep every robot is heard once per step.
LOCKSTEP_SYNC = {'sync_timeout': LOCKSTEP_PATIENCE - 2.0,
                 'neighbor_timeout': LOCKSTEP_PATIENCE - 2.0}
# A robot driven by the Nav2 stand-in: its planner filters the stand-in's TwistStamped (the
# simulator's cmd_vel type), never falls silent within a run (the simulator waits for every
# answer) and counts its own state as stale only when the run has surely stalled.
FILTER_PARAMETERS = {'preferred_source': 'velocity', 'enable_stamped_cmd_vel': True,
                     'stop_pub_timeout': 1.0e9, 'state_timeout': 60.0}
# A robot given its path by the planner_server stand-in: its planner follows it, from the first
# step on (it waits for the path as for its neighbours).
PATH_PARAMETERS = {'preferred_source': 'path', 'wait_for_path': True}
# Parameters the runner sets itself; a scenario's planner block cannot override them.
RUNNER_PARAMETERS = ('use_sim_time', 'goal', 'radius', 'max_speed', 'actuation_std',
                     'goal_tolerance', 'model', 'eta', 'kinematics', 'max_angular_speed',
                     'max_acceleration', 'max_angular_acceleration')


def ros_parameter(value):
    """Format VALUE for `-p name:=value` so that ROS parses it with the same type."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (list, tuple, np.ndarray)):
        return '[' + ', '.join(ros_parameter(item) for item in value) + ']'
    return str(value)


def planned_robots(scenario):
    """Return the robots of SCENARIO that have a planner: all but the scripted ones."""
    return [robot for robot in scenario.robots if robot.scripted is None]


def robot_eta(robot):
    """Return the eta of ROBOT's own planner block, else the default."""
    return float(robot.planner.get('eta', DEFAULT_ETA))


def runner_planner_values(robot, scenario, method, eta, mode='lockstep'):
    """Return the planner parameters the runner sets for ROBOT, typed, in order.

    ETA, if not None, is every planner's; None gives each robot the eta of its planner block.
    The planner block's other parameters follow; every other parameter keeps its default.
    """
    values = {
        'goal': [float(value) for value in robot.goal],
        'radius': float(robot.radius),
        'max_speed': float(robot.max_speed),
        # The robot's known execution error; the ablation plans as if there were none.
        'actuation_std': 0.0 if method == 'prvo-no-ego' else float(robot.noise.actuation_std),
        # Half the scenario's: when the planner's estimate says it arrived, the ground truth is
        # inside the scenario's tolerance.
        'goal_tolerance': scenario.goal_tolerance / 2.0,
        'model': MODEL_OF_METHOD[method],
        'eta': float(eta) if eta is not None else robot_eta(robot),
        # Named rather than discovered: each planner waits for all of them from t_0, so a seed
        # reproduces its run.
        'neighbors': [other.name for other in scenario.robots if other.name != robot.name],
        'kinematics': robot.kinematics,
    }
    if robot.kinematics == 'unicycle':
        values['max_angular_speed'] = float(robot.max_angular_speed)
    # Unlimited is the planner's default (.inf); only limits are passed.
    for limit in ('max_acceleration', 'max_angular_acceleration'):
        if math.isfinite(getattr(robot, limit)):
            values[limit] = float(getattr(robot, limit))
    if robot.upstream is not None:
        values.update(FILTER_PARAMETERS)
    if robot.followed_path is not None:
        values.update(PATH_PARAMETERS)
    if mode == 'lockstep':
        # The simulator waits for every answer, so a planner can wait for every neighbour's
        # odometry of the same stamp however loaded the machine: that makes runs reproducible.
        values.update(LOCKSTEP_SYNC)
    for key, value in robot.planner.items():
        if key not in RUNNER_PARAMETERS:
            values[key] = value
    from prvo_planner.parameters import DEFAULTS

    if scenario.static_world.grid is not None and (
            values.get('map_topic', DEFAULTS['map_topic']) == DEFAULTS['map_topic']):
        # The planner's first plan is on the map the simulator publishes, as in-process.
        values.setdefault('wait_for_map', True)
    return values


def planner_values(robot, scenario, method, eta, mode='lockstep'):
    """Return every planner parameter ROBOT's planner node holds in a run, typed and checked.

    None for a scripted robot: it has no planner.
    """
    from prvo_planner.parameters import DEFAULTS, checked_parameters

    if robot.scripted is not None:
        return None
    return checked_parameters(
        {**DEFAULTS, **runner_planner_values(robot, scenario, method, eta, mode)})


def check_planner_maps(scenario, method, eta):
    """Raise MapTooLargeError if a planner of a run could not build the map the sim publishes.

    Each planner listening on the default map topic builds the static world's grid for its
    own radius and margins; one beyond the bounds would be refused by the planner, and the
    robot would plan as if there were no map.
    """
    from prvo_planner.agent import AgentSettings, check_map_work, map_key_of

    grid = scenario.static_world.grid
    if grid is None:
        return
    for robot in planned_robots(scenario):
        values = planner_values(robot, scenario, method, eta)
        if values['map_topic'] == PLANNER_DEFAULTS['map_topic']:
            check_map_work(grid.shape, grid.resolution, map_key_of(
                AgentSettings.from_parameters(values), values['safety_margin']))


def planner_parameters(robot, scenario, method, eta, mode='lockstep'):
    """Return the `-p` parameters of ROBOT's planner node, in order, ROS-formatted."""
    values = runner_planner_values(robot, scenario, method, eta, mode)
    return {'use_sim_time': 'true',
            **{key: ros_parameter(value) for key, value in values.items()}}


def run_eta(options, scenario):
    """Return the eta of the run: --eta, else the robots' common eta, else the list of them."""
    if options.eta is not None:
        return options.eta
    etas = [robot_eta(robot) for robot in planned_robots(scenario)]
    return etas[0] if len(set(etas)) == 1 else etas


class RunSpec:
    """Everything one run needs: the scenario and the resolved options.

    ETA is the run's eta as reported (see run_eta): a number is given to every planner, a list
    (or None) leaves each robot the eta of its planner block.
    """

    def __init__(self, options, scenario, eta, seed, out_dir):
        self.scenario = scenario
        self.method = options.method
        self.mode = options.mode
        self.engine = getattr(options, 'engine', 'ros')
        # A rosbag2 recording (bag/) and an animation (trajectories.gif) of the run.
        self.bag = getattr(options, 'bag', True)
        self.animation = getattr(options, 'animation', True)
        self.eta = eta
        self.planner_eta = eta if isinstance(eta, (int, float)) else None
        self.seed = seed
        self.out_dir = pathlib.Path(out_dir)
        self.timeout = options.timeout or 10.0 * scenario.duration + 60.0
        self.quiet = options.quiet
        self._sim_command = getattr(options, 'sim_command', None)
        self._planner_command = getattr(options, 'planner_command', None)

    @property
    def sim_command(self):
        """The simulator's argv prefix (the ROS engine's; looked up only when asked for)."""
        if self._sim_command:
            return shlex.split(self._sim_command)
        return package_command('prvo_sim', 'sim', 'prvo_sim.sim_node')

    @property
    def planner_command(self):
        """A planner's argv prefix (the ROS engine's; looked up only when asked for)."""
        if self._planner_command:
            return shlex.split(self._planner_command)
        return package_command('prvo_planner', 'planner', 'prvo_planner.planner_node')

    @property
    def stand_in_command(self):
        """The Nav2 stand-in's argv prefix (the ROS engine's)."""
        return package_command('prvo_sim', 'nav2_stand_in', 'prvo_sim.upstream_node')

    @property
    def path_stand_in_command(self):
        """The planner_server stand-in's argv prefix (the ROS engine's)."""
        return package_command('prvo_sim', 'planner_server_stand_in',
                               'prvo_sim.planned_path_node')

    def own_nodes(self):
        """Return the fully qualified names of the nodes the run's children create."""
        return {f'/{SIM_NODE}', *(f'/{robot.name}/{PLANNER_NODE}'
                                   for robot in planned_robots(self.scenario)),
                *(f'/{robot.name}/{STAND_IN_NODE}' for robot in self.scenario.robots
                  if robot.upstream is not None),
                *(f'/{robot.name}/{PATH_STAND_IN_NODE}' for robot in self.scenario.robots
                  if robot.followed_path is not None)}


def stand_in_parameters(robot, scenario, mode):
    """Return the `-p` parameters of ROBOT's Nav2 stand-in, ROS-formatted.

    As the in-process engine's (`prvo_sim.engine.upstream_of`); in lockstep it answers each
    odometry message with its stamp.
    """
    return {'use_sim_time': 'true',
            'waypoints': ros_parameter(robot.upstream.waypoints.ravel()),
            'speed': ros_parameter(robot.upstream.speed), 'kinematics': robot.kinematics,
            'goal_tolerance': ros_parameter(scenario.goal_tolerance / 2.0),
            'max_angular_speed': ros_parameter(robot.max_angular_speed),
            'answer_odometry': ros_parameter(mode == 'lockstep'),
            'enable_stamped_cmd_vel': 'true'}


def path_stand_in_parameters(robot):
    """Return the `-p` parameters of ROBOT's planner_server stand-in, ROS-formatted.

    As the in-process engine's (`prvo_sim.engine.path_of`).
    """
    return {'use_sim_time': 'true',
            'waypoints': ros_parameter(robot.followed_path.waypoints.ravel())}


def start_stand_ins(children, spec):
    """Start the Nav2 stand-in of every robot driven upstream, and of every one given a path."""
    for robot in spec.scenario.robots:
        stand_ins = []
        if robot.upstream is not None:
            stand_ins.append((spec.stand_in_command, STAND_IN_NODE, 'stand_in',
                              stand_in_parameters(robot, spec.scenario, spec.mode)))
        if robot.followed_path is not None:
            stand_ins.append((spec.path_stand_in_command, PATH_STAND_IN_NODE, 'path_stand_in',
                              path_stand_in_parameters(robot)))
        for command, node, label, parameters in stand_ins:
            argv = [*command, '--ros-args', '-r', f'__ns:=/{robot.name}', '-r', f'__node:={node}']
            for key, value in parameters.items():
                argv += ['-p', f'{key}:={value}']
            children.start(f'{label}_{robot.name}', argv)


def start_planners(children, spec):
    """Start one planner per robot that is not scripted."""
    scenario = spec.scenario
    for robot in planned_robots(scenario):
        argv = [*spec.planner_command, '--ros-args', '-r', f'__ns:=/{robot.name}',
                '-r', f'__node:={PLANNER_NODE}']
        parameters = planner_parameters(robot, scenario, spec.method, spec.planner_eta,
                                        spec.mode)
        for key, value in parameters.items():
            argv += ['-p', f'{key}:={value}']
        children.start(f'planner_{robot.name}', argv)


def sim_parameters(scenario, mode, seed, observers=()):
    """Return the `-p` parameters of the simulator running SCENARIO, ROS-formatted.

    The simulator takes no step until every node in OBSERVERS listens to it.
    """
    parameters = {'scenario': str(pathlib.Path(scenario.path).resolve()), 'mode': mode,
                  'seed': str(int(seed)), 'step_timeout': repr(STEP_TIMEOUT),
                  'startup_timeout': repr(LOCKSTEP_PATIENCE)}
    if observers:
        parameters['observers'] = '[' + ', '.join(f"'{name}'" for name in observers) + ']'
    return parameters


def start_sim(children, spec, observer):
    """Start the simulator, which takes no step until node OBSERVER listens to it."""
    argv = [*spec.sim_command, '--ros-args', '-r', f'__node:={SIM_NODE}']
    for key, value in sim_parameters(spec.scenario, spec.mode, spec.seed, [observer]).items():
        argv += ['-p', f'{key}:={value}']
    children.start('sim', argv)


class _Watch:
    """What every waiting loop of a run checks: children alive, no intruder, wall-clock limit."""

    def __init__(self, recorder, children, spec):
        self._recorder = recorder
        self._children = children
        self._own_nodes = spec.own_nodes()
        self._timeout = spec.timeout
        self._started = time.monotonic()
        self._next_graph_check = self._started

    def failure(self):
        """Return a one-line failure, or None while the run may go on."""
        now = time.monotonic()
        if self._recorder.lost is not None:
            return self._recorder.lost
        exited = self._children.first_exited()
        if exited is not None:
            return (f'{exited.label} exited with code {exited.returncode} '
                    f'(log: {exited.log_path})')
        if now - self._started > self._timeout:
            return f'timed out after {self._timeout:g} s of wall time'
        if now >= self._next_graph_check:
            self._next_graph_check = now + GRAPH_CHECK_PERIOD
            return self._recorder.intruders(self._own_nodes)
        return None


def wait_for_planners(recorder, watch):
    """Spin until the recorder has matched every planner's publishers; return None, or why not."""
    started = time.monotonic()
    while True:
        recorder.spin_for(0.05)
        failure = watch.failure()
        if failure is not None:
            return failure
        unheard = recorder.unheard_planners()
        if not unheard:
            return None
        if time.monotonic() - started > STARTUP_LIMIT:
            return (f'no cmd_vel and diagnostics publishers of {", ".join(unheard)} matched '
                    f'within {STARTUP_LIMIT:g} s of starting the planners')


def wait_for_end(recorder, watch, spec, progress):
    """Record until the run ends; return (its `Ending`, the end time [s] or None) or a failure.

    The end-of-run rule sees every step the recording holds, in order, once no robot's
    ground truth for it can still come (each robot's messages arrive in order): so a ROS run
    ends at the step an in-process run of the same team ends at, however late the runner
    looks.
    """
    scenario = spec.scenario
    rule = ArrivalRule.of(scenario)
    steps = RecordedSteps([robot.name for robot in scenario.robots])
    started = time.monotonic()
    next_progress = started
    while True:
        recorder.spin_for(0.05)
        now = time.monotonic()
        failure = watch.failure()
        if failure is not None:
            return failure
        finished = recorder.sim_status is not None and recorder.sim_status.finished
        ground_truth = recorder.ground_truth
        if not steps.heard_all(ground_truth):
            if finished:
                return ('the simulator finished before the recorder received ground truth of '
                        'every robot')
            if now - started > STARTUP_LIMIT:
                return f'no ground truth from every robot within {STARTUP_LIMIT:g} s'
            continue
        for sim_time, positions in steps.completed(ground_truth):
            if rule.step(sim_time, positions):
                return Ending.ARRIVED, sim_time
        if now >= next_progress and rule.time is not None:
            progress(rule.time, rule.arrived_count, now - started)
            next_progress = now + PROGRESS_PERIOD
        if finished:
            return Ending.DURATION, None


class ArrivalRule:
    """The rule that ends a run: every planned robot within the goal tolerance for SETTLE_TIME.

    Fed a run's steps in order, it says at which step the run ends: a function of the simulated
    run only, so identical runs end at the same step on either engine. Scripted robots do not
    arrive: the planned ones end the run.
    """

    def __init__(self, goals, goal_tolerance, planned):
        """GOALS (N, 2) [m]; GOAL_TOLERANCE [m]; PLANNED (N,) bool: the robots that must arrive."""
        self._goals = np.asarray(goals, dtype=float)
        self._goal_tolerance = goal_tolerance
        self._planned = np.asarray(planned, dtype=bool)
        self._settled_since = None
        self.time = None
        self.arrived_count = 0

    @classmethod
    def of(cls, scenario):
        """Return the rule of SCENARIO's robots and goal tolerance."""
        return cls([robot.goal for robot in scenario.robots], scenario.goal_tolerance,
                   [robot.scripted is None for robot in scenario.robots])

    @property
    def all_arrived(self):
        """Whether every planned robot has been at its goal since some step, to the last one."""
        return self._settled_since is not None

    def step(self, sim_time, positions):
        """Take the step at SIM_TIME [s] with POSITIONS (N, 2); return whether the run ends."""
        arrived = (np.linalg.norm(np.asarray(positions)[:, :2] - self._goals, axis=1)
                   <= self._goal_tolerance)[self._planned]
        self.time = float(sim_time)
        self.arrived_count = int(arrived.sum())
        if not arrived.all():
            self._settled_since = None
            return False
        if self._settled_since is None:
            self._settled_since = self.time
        return self.time - self._settled_since >= SETTLE_TIME - TIME_EPSILON


class RecordedSteps:
    """The steps of a ROS recording that every robot's ground truth has, each given once.

    A step is complete once every robot has it; it is final once every robot has a later
    one (a robot's messages arrive in order, so a step it skipped never comes).
    """

    def __init__(self, robot_names):
        """ROBOT_NAMES: the robots, in the scenario's order."""
        self._robot_names = list(robot_names)
        self._done = -1  # ns: the last stamp given

    def heard_all(self, ground_truth):
        """Whether GROUND_TRUTH ({robot: {stamp ns: state}}) holds a message of every robot."""
        return all(ground_truth.get(name) for name in self._robot_names)

    def completed(self, ground_truth):
        """Yield (time [s], positions (N, 2)) of each step newly complete and final, in order."""
        frontier = min(max(ground_truth[name]) for name in self._robot_names)
        first = ground_truth[self._robot_names[0]]
        stamps = sorted(stamp for stamp in first if self._done < stamp <= frontier and all(
            stamp in ground_truth[name] for name in self._robot_names))
        self._done = max(self._done, frontier)
        for stamp in stamps:
            yield stamp * 1e-9, np.array([ground_truth[name][stamp][:2]
                                          for name in self._robot_names])


def run_once(spec, domain_id, monitor=None):
    """Run SPEC once on DOMAIN_ID; write its outputs; return its `RunResult`.

    The caller holds DOMAIN_ID (and has checked it for strangers). Results first: once the run
    has ended, the team is told to stop, the recorder's listener is stopped (bounded: it is
    killed if it hangs), the results are written from what was recorded, and only then does
    the runner wait for the children to exit (SIGKILL after SHUTDOWN_GRACE). SIGINT, SIGTERM
    or SIGHUP end the run (the result's `interrupted`); one during the teardown cuts the
    children's grace and the animation short, never the other results. MONITOR, if given,
    watches the run from inside (the team benchmark measures the children with it):
    monitor.started(children, recorder) is called once every child has been started,
    monitor.ending(children, recorder) once the run has ended, just before the children are
    stopped (not when the run was interrupted).
    """
    from prvo_sim.runner.recorder import Recorder, RecorderError

    scenario = spec.scenario
    log_dir = spec.out_dir / 'logs'
    children = Children(child_environment(domain_id), log_dir)
    recorder = None
    failure = None
    ending = Ending.FAILED
    interrupted = None
    end_time = None
    progress = ProgressLine(spec, quiet=spec.quiet)
    started = time.monotonic()
    try:
        recorder = Recorder(domain_id, [robot.name for robot in scenario.robots],
                            planned_names=[robot.name for robot in planned_robots(scenario)],
                            record_bag=spec.bag, with_map=not scenario.static_world.empty)
        # The first file of the run: a run that never got here leaves the folder alone.
        log_dir.mkdir(parents=True, exist_ok=True)
        watch = _Watch(recorder, children, spec)
        # Before the planners: a stand-in is then up before the simulator's first step.
        start_stand_ins(children, spec)
        start_planners(children, spec)
        failure = wait_for_planners(recorder, watch)
        if failure is None:
            start_sim(children, spec, recorder.name)
            if monitor is not None:
                monitor.started(children, recorder)
            end = wait_for_end(recorder, watch, spec, progress)
            if isinstance(end, str):
                failure = end
            else:
                ending, end_time = end
        if failure is None:
            failure = recorder.recording_gaps(scenario.dt, spec.mode == 'lockstep',
                                              RECORDING_GRACE, until=end_time)
            if failure is not None:
                ending = Ending.FAILED
        if monitor is not None:
            monitor.ending(children, recorder)
    except RunInterruptedError as interruption:
        interrupted = interruption.signum
        ending = Ending.INTERRUPTED
        failure = f'interrupted by {interruption}'
    except RecorderError as error:
        failure = str(error)
    with INTERRUPTS.teardown() as teardown:
        progress.finish()
        try:
            children.interrupt()
            if recorder is not None:
                recorder.close()
            if not children.processes and interrupted is not None:
                # Interrupted before anything started: nothing to report, nothing written.
                raise RunInterruptedError(interrupted)
            spec.out_dir.mkdir(parents=True, exist_ok=True)
            recording = recorder.recording(until=end_time) if recorder is not None else None
            run_metrics = write_outputs(spec, recording, ending, failure,
                                        time.monotonic() - started)
        finally:
            children.stop()
        if interrupted is None:
            interrupted = teardown.last_signal
    return RunResult(ending, run_metrics, interrupted)


class ProgressLine:
    """A one-line progress report on stderr, rewritten in place on a terminal."""

    def __init__(self, spec, quiet):
        self._spec = spec
        self._quiet = quiet
        self._tty = sys.stderr.isatty()
        self._last_printed = -math.inf
        self._written = False

    def __call__(self, sim_time, arrived, wall_time):
        """Report SIM_TIME, the number of ARRIVED planned robots and WALL_TIME."""
        if self._quiet:
            return
        scenario = self._spec.scenario
        line = (f'{scenario.name} seed {self._spec.seed}: sim {sim_time:5.1f}/'
                f'{scenario.duration:g} s, arrived {arrived}/{len(planned_robots(scenario))}, '
                f'wall {wall_time:5.1f} s')
        if self._tty:
            sys.stderr.write('\r' + line + '   ')
            sys.stderr.flush()
            self._written = True
        elif wall_time - self._last_printed >= 5.0:
            print(line, file=sys.stderr, flush=True)
            self._last_printed = wall_time

    def finish(self):
        """End the rewritten line."""
        if self._written:
            sys.stderr.write('\n')
            sys.stderr.flush()
