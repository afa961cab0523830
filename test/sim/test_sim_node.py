"""The `sim` executable as a real process, driven by a probe-side stand-in for the planners."""

import signal
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from kinematics_replay import replay
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock

from prvo_msgs_util import (
    CLOCK_QOS,
    CMD_VEL_QOS,
    CONTACT_QOS,
    DIAGNOSTICS_QOS,
    ODOM_QOS,
    diagnostic_values,
    make_twist,
    odometry_to_measurement,
    quiet_publisher_events,
    quiet_subscription_events,
    seconds_to_stamp,
    stamp_to_seconds,
)
from prvo_sim.scenario import find_scenario, load_scenario

ROBOTS = ('robot_0', 'robot_1')
# headon2: robot_0 starts at (-4, 0), robot_1 at (4, 0); these drive them into each other.
HEAD_ON = {'robot_0': (1.0, 0.0), 'robot_1': (-1.0, 0.0)}
HEADON2 = load_scenario(find_scenario('headon2'))


def stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Planners:
    """Probe-side planners: answer each robot's odometry with a constant TwistStamped.

    Robots not in COMMANDS get a cmd_vel publisher but never answer; ROGUE robots answer with a
    NaN command instead. FRAMES gives a robot's command frame (default map). ANSWER_UNTIL_STEP
    (one step for all, or {robot: step}) ends a robot's answers after that step. SCRIPT(robot,
    step) may return the list of (velocity, stamp offset [s]) to send instead of the answer.
    Odometry and ground truth (unless GROUND_TRUTH is false) are recorded per robot, keyed by
    stamp; `odometry_count` counts every odometry message per stamp, re-sent ones included.
    """

    def __init__(self, probe, commands, rogue=(), answer_until_step=None, frames=None,
                 script=None, ground_truth=True):
        self._probe = probe
        self._commands = commands
        self._frames = frames or {}
        self._rogue = rogue
        self._script = script
        if not isinstance(answer_until_step, dict):
            answer_until_step = dict.fromkeys(ROBOTS, answer_until_step)
        self._answer_until_step = answer_until_step
        self.lock = threading.Lock()
        self.odometry = {robot: {} for robot in ROBOTS}
        self.odometry_count = {robot: {} for robot in ROBOTS}
        self.ground_truth = {robot: {} for robot in ROBOTS}
        self.arrival_times = {robot: {} for robot in ROBOTS}
        self._subscriptions = []
        self._publishers = {}
        for robot in ROBOTS:
            # No QoS event handlers: close() destroys these while the probe spins, and an event
            # handler destroyed mid-wait kills the spin thread (rclpy's InvalidHandle).
            self._publishers[robot] = probe.node.create_publisher(
                TwistStamped, f'/{robot}/cmd_vel', CMD_VEL_QOS,
                event_callbacks=quiet_publisher_events())
            self._subscriptions.append(probe.node.create_subscription(
                Odometry, f'/{robot}/odom',
                lambda msg, robot=robot: self._on_odometry(robot, msg), ODOM_QOS,
                event_callbacks=quiet_subscription_events()))
            if ground_truth:
                self.subscribe_ground_truth(robot)

    def subscribe_ground_truth(self, robot):
        """Record ROBOT's ground truth from now on."""
        self._subscriptions.append(self._probe.node.create_subscription(
            Odometry, f'/{robot}/ground_truth',
            lambda msg: self._keep(self.ground_truth[robot], msg), ODOM_QOS,
            event_callbacks=quiet_subscription_events()))

    def _keep(self, by_stamp, msg):
        with self.lock:
            by_stamp.setdefault(stamp_ns(msg.header.stamp), msg)

    def _on_odometry(self, robot, msg):
        stamp = stamp_ns(msg.header.stamp)
        step = round(stamp / (HEADON2.dt * 1e9))
        with self.lock:
            self.arrival_times[robot].setdefault(stamp, time.monotonic())
            counts = self.odometry_count[robot]
            counts[stamp] = counts.get(stamp, 0) + 1
        self._keep(self.odometry[robot], msg)
        last_step = self._answer_until_step.get(robot)
        if last_step is not None and step > last_step:
            return
        scripted = self._script(robot, step) if self._script else None
        if scripted is not None:
            answers = scripted
        elif robot in self._rogue:
            answers = [((float('nan'), 0.0), 0.0)]
        elif robot in self._commands:
            answers = [(self._commands[robot], 0.0)]
        else:
            return
        for velocity, stamp_offset in answers:
            answer = TwistStamped(twist=make_twist(velocity))
            answer.header.stamp = msg.header.stamp if not stamp_offset else seconds_to_stamp(
                stamp_to_seconds(msg.header.stamp) + stamp_offset)
            answer.header.frame_id = self._frames.get(robot, 'map')
            self._publishers[robot].publish(answer)

    def steps(self, robot, what='odometry'):
        """Return the step indices recorded so far for ROBOT, sorted."""
        with self.lock:
            stamps = sorted(getattr(self, what)[robot])
        return [round(stamp / (HEADON2.dt * 1e9)) for stamp in stamps]

    def close(self):
        """Stop answering and recording."""
        for subscription in self._subscriptions:
            self._probe.node.destroy_subscription(subscription)
        for publisher in self._publishers.values():
            self._probe.node.destroy_publisher(publisher)


def start_sim(children, ros2_executable, label, **parameters):
    argv = [ros2_executable('prvo_sim', 'sim'), '--ros-args']
    for name, value in {'scenario': 'headon2', **parameters}.items():
        argv += ['-p', f'{name}:={value}']
    return children.start(label, argv)


def latest_statuses(diagnostics):
    """Return {status name: values} of the newest /diagnostics array from the sim."""
    for array in reversed(diagnostics):
        statuses = {status.name: diagnostic_values(status) for status in array.status}
        if 'prvo_sim' in statuses:
            return statuses
    return {}


def test_lockstep_noise_covariance_contact_and_sigint(probe, children, ros2_executable):
    contacts = probe.record(DiagnosticArray, '/prvo_sim/contacts', CONTACT_QOS)
    clock = probe.record(Clock, '/clock', CLOCK_QOS)
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    planners = Planners(probe, HEAD_ON)
    sim = start_sim(children, ros2_executable, 'sim', step_timeout=5.0)

    probe.wait_until(lambda: contacts, 25.0, 'a contact event')
    (event,) = contacts[0].status
    values = diagnostic_values(event)
    assert (values['robot_a'], values['robot_b']) == ROBOTS
    # Closing at 2 m/s from 8 m apart, contact when the gap is below 0.3 + 0.3 m: t ~ 3.7 s.
    assert float(values['time']) == pytest.approx(3.7, abs=0.25)
    assert float(values['distance']) < 0.6
    probe.wait_until(lambda: 'contact at t=' in children.output(sim), 5.0, 'the contact log')

    contact_step = round(float(values['time']) / HEADON2.dt)
    probe.wait_until(lambda: len(planners.steps('robot_1', 'ground_truth')) > contact_step,
                     5.0, 'ground truth up to the contact')
    assert children.interrupt(sim) == 0

    for robot, command in HEAD_ON.items():
        steps = planners.steps(robot)
        # Lockstep: every step published, none skipped, none repeated under another stamp.
        assert steps == list(range(len(steps)))
        assert len(steps) > contact_step
        start = HEADON2.robots[ROBOTS.index(robot)].start
        position_errors, velocity_errors = [], []
        for step in range(1, contact_step + 1):
            truth = odometry_to_measurement(planners.ground_truth[robot][
                round(step * HEADON2.dt * 1e9)])
            noisy = odometry_to_measurement(planners.odometry[robot][
                round(step * HEADON2.dt * 1e9)])
            # A random walk of 0.05 m/s * 0.1 s per step around the commanded path (5 sigma).
            expected = start + np.array(command) * step * HEADON2.dt
            np.testing.assert_allclose(
                truth.position, expected, atol=5 * 0.05 * HEADON2.dt * np.sqrt(step))
            np.testing.assert_allclose(truth.velocity, command, atol=0.25)
            assert noisy.child_frame_id == f'{robot}/base_link'
            np.testing.assert_allclose(noisy.covariance, 0.05 ** 2 * np.eye(4), atol=1e-15)
            np.testing.assert_allclose(truth.covariance, np.zeros((4, 4)))
            position_errors.append(noisy.position - truth.position)
            velocity_errors.append(noisy.velocity - truth.velocity)
        # The published variances are the ones actually applied: about 0.05 m, 0.05 m/s.
        for errors in (position_errors, velocity_errors):
            assert 0.035 < np.std(errors) < 0.065
    last_step_ns = round(planners.steps('robot_0')[-1] * HEADON2.dt * 1e9)
    # /clock and the planners' topics arrive independently: the clock of the last step may
    # still be on its way when the planner's answer to it is in.
    probe.wait_until(lambda: clock and max(stamp_ns(message.clock) for message in clock)
                     >= last_step_ns, 5.0, 'the clock of the last step')
    statuses = latest_statuses(diagnostics)
    assert statuses['prvo_sim']['deadline_misses'] == '0'
    assert statuses['prvo_sim']['mode'] == 'lockstep'
    assert int(statuses['prvo_sim']['contacts']) >= 1


def test_silent_robot_times_out_and_bad_command_is_skipped(probe, children, ros2_executable):
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # robot_0 answers every odometry; robot_1 only ever sends NaN, which must not count.
    planners = Planners(probe, {'robot_0': HEAD_ON['robot_0']}, rogue=('robot_1',))
    step_timeout = 1.0
    # The first step waits for robot_0's answer to the (re-sent) t_0, robot_1's never comes.
    sim = start_sim(children, ros2_executable, 'sim', step_timeout=step_timeout,
                    startup_timeout=5.0)

    def stepped_four_times():
        return int(latest_statuses(diagnostics).get('prvo_sim', {}).get('step', 0)) >= 4
    probe.wait_until(stepped_four_times, 30.0, 'four steps')
    probe.wait_until(lambda: 'skipping /robot_1/cmd_vel: twist.linear contains NaN'
                     in children.output(sim), 5.0, 'the NaN warning')
    assert sim.poll() is None

    statuses = latest_statuses(diagnostics)
    step = int(statuses['prvo_sim']['step'])
    assert statuses['prvo_sim/robot_1']['deadline_misses'] == str(step)
    assert statuses['prvo_sim/robot_0']['deadline_misses'] == '0'
    assert statuses['prvo_sim']['deadline_misses'] == str(step)
    with planners.lock:
        # A loaded probe can miss a message; the steps it saw are enough.
        received = planners.arrival_times['robot_0']
        arrivals = {k: received[round(k * HEADON2.dt * 1e9)] for k in range(1, step + 1)
                    if round(k * HEADON2.dt * 1e9) in received}
    first, last = min(arrivals), max(arrivals)
    assert last - first >= 2
    # Each step waited for robot_1 until the timeout, however fast robot_0 answered: a lower
    # bound that a slow host only widens (one timeout of slack for the probe's receive delays).
    assert arrivals[last] - arrivals[first] >= (last - first - 1) * step_timeout
    # robot_0's last good command stands: it keeps moving at its commanded speed.
    x = float(statuses['prvo_sim/robot_0']['x'])
    assert x == pytest.approx(-4.0 + step * HEADON2.dt,
                              abs=5 * 0.05 * HEADON2.dt * np.sqrt(step))
    assert children.interrupt(sim) == 0


def test_realtime_steps_on_the_wall_clock(probe, children, ros2_executable):
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # robot_1 starts facing its goal at -x: "forward" in its base_link is -x in the world.
    # robot_0 answers the t_0 odometry only, so that the first step need not wait long.
    planners = Planners(probe, {'robot_0': (0.0, 0.0), 'robot_1': (1.0, 0.0)},
                        frames={'robot_1': 'robot_1/base_link'},
                        answer_until_step={'robot_0': 0, 'robot_1': None})
    rate = 20.0
    # Lockstep would wait an hour for robot_0 at every step: steps come from the wall timer.
    sim = start_sim(children, ros2_executable, 'sim', mode='realtime', rate=rate,
                    step_timeout=3600.0, startup_timeout=60.0)

    def stepped(count):
        return int(latest_statuses(diagnostics).get('prvo_sim', {}).get('step', 0)) >= count
    probe.wait_until(lambda: stepped(30), 60.0, 'thirty realtime steps')
    statuses = latest_statuses(diagnostics)
    assert children.interrupt(sim) == 0

    step = int(statuses['prvo_sim']['step'])
    assert statuses['prvo_sim']['mode'] == 'realtime'
    # The first step waited for every answer to t_0; robot_0 misses every tick after it.
    assert statuses['prvo_sim/robot_0']['deadline_misses'] == str(step - 1)
    misses = int(statuses['prvo_sim/robot_1']['deadline_misses'])
    assert misses < step
    # robot_1 moves at 1 m/s on every step it answered in time (the first one at least); a
    # late one reuses its command, or executes zero once it was silent beyond cmd_timeout.
    travelled = 4.0 - float(statuses['prvo_sim/robot_1']['x'])
    tolerance = 5 * 0.05 * HEADON2.dt * np.sqrt(step)
    assert (step - misses) * HEADON2.dt - tolerance <= travelled <= step * HEADON2.dt + tolerance
    with planners.lock:
        received = planners.arrival_times['robot_1']
        arrivals = {round(stamp / (HEADON2.dt * 1e9)): at for stamp, at in received.items()}
    # Ticks at most 20 per second, however fast the answers: a lower bound on the wall time
    # from tick 1 to the last, with half a second of slack for the probe's receive delays.
    first, last = min(k for k in arrivals if k >= 1), max(arrivals)
    assert last - first >= 20
    assert arrivals[last] - arrivals[first] >= (last - first) / rate - 0.5


def ground_truth_positions(planners, robot, steps):
    """Return {step: ground truth position} of ROBOT for the recorded STEPS."""
    with planners.lock:
        received = dict(planners.ground_truth[robot])
    return {step: odometry_to_measurement(received[round(step * HEADON2.dt * 1e9)]).position
            for step in steps if round(step * HEADON2.dt * 1e9) in received}


def test_observer_sees_every_step_from_t0(probe, children, ros2_executable):
    observer = probe.node.get_fully_qualified_name()
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # Both robots answer every odometry; the observer's ground truth subscriptions come late.
    planners = Planners(probe, HEAD_ON, ground_truth=False)
    sim = start_sim(children, ros2_executable, 'sim', observers=f"['{observer}']")

    probe.wait_until(
        lambda: any(status.message == f'waiting for observers: {observer}'
                    for array in diagnostics for status in array.status), 20.0,
        'a status saying whom the sim waits for')
    # Both robots have answered the t_0 odometry and had it re-sent: a sim that did not wait
    # for the observer would have stepped on their first answers.
    probe.wait_until(
        lambda: all(planners.odometry_count[robot].get(0, 0) >= 3 for robot in ROBOTS), 20.0,
        't_0 odometry re-sent to answering robots')
    probe.wait_until(
        lambda: f'{observer} has no subscription on /robot_0/ground_truth' in
        children.output(sim), 5.0, 'the log naming the missing observer topics')
    assert all(planners.steps(robot) == [0] for robot in ROBOTS)
    # An observer listens to the clock too (a recording starts at t_0).
    probe.record(Clock, '/clock', CLOCK_QOS)
    for robot in ROBOTS:
        planners.subscribe_ground_truth(robot)
    probe.wait_until(
        lambda: all(len(planners.steps(robot, 'ground_truth')) > 5 for robot in ROBOTS),
        30.0, 'five steps once the observer subscribed')
    assert children.interrupt(sim) == 0
    for robot in ROBOTS:
        # Every step from t_0 on, t_0 included.
        steps = planners.steps(robot, 'ground_truth')
        assert steps == list(range(len(steps)))
        start = HEADON2.robots[ROBOTS.index(robot)].start
        np.testing.assert_array_equal(ground_truth_positions(planners, robot, [0])[0], start)


def test_realtime_robot_stops_when_its_commands_stop(probe, children, ros2_executable):
    # Each robot answers the t_0 odometry only, then its planner is gone.
    planners = Planners(probe, HEAD_ON, answer_until_step=0)
    cmd_timeout = 0.3
    sim = start_sim(children, ros2_executable, 'sim', mode='realtime', rate=20.0,
                    cmd_timeout=cmd_timeout, startup_timeout=60.0)
    last_step = 40
    probe.wait_until(
        lambda: all(last_step in planners.steps(robot, 'ground_truth') for robot in ROBOTS),
        60.0, f'{last_step} realtime steps')
    assert children.interrupt(sim) == 0
    output = children.output(sim)
    # Ticks are at least 1 / 20 s apart: from tick 7 on the last command is older than 0.3 s.
    first_stopped = 10
    noise_walk = 5 * 0.05 * HEADON2.dt * np.sqrt(last_step - first_stopped)
    for robot, command in HEAD_ON.items():
        positions = ground_truth_positions(planners, robot, range(1, last_step + 1))
        start = HEADON2.robots[ROBOTS.index(robot)].start
        # The first step executes the robot's one command.
        np.testing.assert_allclose(positions[1] - start, np.array(command) * HEADON2.dt,
                                   atol=5 * 0.05 * HEADON2.dt)
        # Then it stops: it moves only by its actuation noise (1 m/s would be 3 m).
        assert np.linalg.norm(positions[last_step] - positions[first_stopped]) < noise_walk
        assert f'no cmd_vel from {robot} for' in output


def test_lockstep_robot_that_stays_silent_is_stopped(probe, children, ros2_executable):
    # robot_0 answers until step 3, then is silent; robot_1 answers every step.
    planners = Planners(probe, HEAD_ON, answer_until_step={'robot_0': 3, 'robot_1': None})
    sim = start_sim(children, ros2_executable, 'sim', step_timeout=0.2, cmd_timeout=0.5)
    last_step = 20
    probe.wait_until(
        lambda: all(last_step in planners.steps(robot, 'ground_truth') for robot in ROBOTS),
        60.0, f'{last_step} steps')
    assert children.interrupt(sim) == 0
    positions = ground_truth_positions(planners, 'robot_0', range(1, last_step + 1))
    # Its misses start at step 4 (the step to t_5); 0.2 s apart, the silence exceeds 0.5 s at
    # the fourth one: from t_8 on it executes zero velocity.
    first_stopped = 8
    noise_walk = 5 * 0.05 * HEADON2.dt * np.sqrt(last_step - first_stopped)
    assert np.linalg.norm(positions[last_step] - positions[first_stopped]) < noise_walk
    # An isolated miss still reuses the last command: it moved on at t_5.
    assert positions[5][0] - positions[4][0] > HEADON2.dt - 5 * 0.05 * HEADON2.dt
    assert 'no cmd_vel from robot_0 for' in children.output(sim)
    # robot_1 answered throughout: it kept its speed.
    robot_1 = ground_truth_positions(planners, 'robot_1', [1, last_step])
    assert robot_1[1][0] - robot_1[last_step][0] == pytest.approx(
        (last_step - 1) * HEADON2.dt, abs=5 * 0.05 * HEADON2.dt * np.sqrt(last_step))


def test_bad_and_duplicate_commands_are_skipped(probe, children, ros2_executable):
    def robot_0_script(robot, step):
        if robot != 'robot_0':
            return None
        bad = {3: [((0.0, 5000.0), 0.0)], 5: [((float('inf'), 0.0), 0.0)],
               7: [((0.0, 1.0), 1000.0)],
               # Stamped 0.04 s: t_0's, 35 steps before the odometry it comes after.
               35: [((0.0, 1.0), 0.04 - 35 * HEADON2.dt)]}
        # Every good answer is sent twice.
        return bad.get(step, [(HEAD_ON['robot_0'], 0.0)] * 2)
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    planners = Planners(probe, HEAD_ON, script=robot_0_script)
    # The step timeout exceeds the simulator's 2 s warning throttle: each bad answer is logged.
    sim = start_sim(children, ros2_executable, 'sim', step_timeout=3.0, startup_timeout=30.0)
    last_step = 37
    probe.wait_until(
        lambda: all(last_step in planners.steps(robot, 'ground_truth') for robot in ROBOTS),
        60.0, f'{last_step} steps')
    probe.wait_until(lambda: int(latest_statuses(diagnostics).get('prvo_sim', {}).get(
        'step', 0)) >= last_step, 10.0, 'the status of the last step')
    assert sim.poll() is None
    statuses = latest_statuses(diagnostics)
    assert children.interrupt(sim) == 0
    output = children.output(sim)
    assert 'skipping /robot_0/cmd_vel: speed 5000.000 m/s' in output
    assert 'skipping /robot_0/cmd_vel: twist.linear contains NaN or inf' in output
    assert 'skipping /robot_0/cmd_vel: stamp 1000.700 s is after' in output
    assert 'skipping /robot_0/cmd_vel: stamp 0.040 s is' in output
    # Steps 3, 5, 7 and 35 got no usable answer from robot_0: four misses, each reusing (1, 0);
    # the duplicates did not step twice (every step published once, none skipped).
    step = int(statuses['prvo_sim']['step'])
    assert statuses['prvo_sim/robot_0']['deadline_misses'] == '4'
    assert statuses['prvo_sim/robot_1']['deadline_misses'] == '0'
    for robot in ROBOTS:
        steps = planners.steps(robot)
        assert steps == list(range(len(steps)))
    positions = ground_truth_positions(planners, 'robot_0', range(1, step + 1))
    start = HEADON2.robots[0].start
    np.testing.assert_allclose(
        positions[step], start + np.array(HEAD_ON['robot_0']) * step * HEADON2.dt,
        atol=5 * 0.05 * HEADON2.dt * np.sqrt(step))


def run_for_steps(probe, children, ros2_executable, label, seed, steps):
    """Run sim with SEED until both robots have STEPS steps; return positions and odometry."""
    planners = Planners(probe, HEAD_ON, answer_until_step=steps)
    sim = start_sim(children, ros2_executable, label, seed=seed)
    probe.wait_until(
        lambda: all(len(planners.steps(robot, 'ground_truth')) > steps for robot in ROBOTS),
        60.0, f'{steps} steps of {label}')
    assert children.interrupt(sim) == 0
    planners.close()
    trajectories = []
    for robot in ROBOTS:
        for source in (planners.ground_truth[robot], planners.odometry[robot]):
            trajectories.append([
                odometry_to_measurement(source[round(k * HEADON2.dt * 1e9)]).position
                # From t_1: t_0 can go out before the probe's subscriptions have matched.
                for k in range(1, steps + 1)])
    return np.array(trajectories)


def test_same_seed_gives_the_same_run(probe, children, ros2_executable):
    first = run_for_steps(probe, children, ros2_executable, 'first', 42, 15)
    second = run_for_steps(probe, children, ros2_executable, 'second', 42, 15)
    other_seed = run_for_steps(probe, children, ros2_executable, 'other', 43, 15)
    np.testing.assert_array_equal(first, second)
    # The seed parameter really reaches the noise: another seed, other trajectories.
    assert np.abs(first - other_seed).min() > 0.0


def test_lockstep_run_is_the_kinematics_replay_of_its_commands(probe, children, ros2_executable):
    steps = 15
    planners = Planners(probe, HEAD_ON, answer_until_step=steps)
    sim = start_sim(children, ros2_executable, 'sim', seed=7)
    probe.wait_until(
        lambda: all(len(planners.steps(robot, 'ground_truth')) > steps for robot in ROBOTS),
        60.0, f'{steps} steps')
    assert children.interrupt(sim) == 0

    # The node's draws, step by step, in the order it made them before TeamWorld existed.
    expected = replay(HEADON2, 7, [[HEAD_ON[robot] for robot in ROBOTS]] * steps)
    for index, robot in enumerate(ROBOTS):
        # From t_1: t_0 can go out before the probe's subscriptions have matched.
        for step in range(1, steps + 1):
            stamp = round(step * HEADON2.dt * 1e9)
            truth = odometry_to_measurement(planners.ground_truth[robot][stamp])
            noisy = odometry_to_measurement(planners.odometry[robot][stamp])
            for value, name in ((truth.position, 'positions'), (truth.velocity, 'velocities'),
                                (noisy.position, 'measured_positions'),
                                (noisy.velocity, 'measured_velocities'),
                                (truth.yaw, 'yaws'), (noisy.yaw, 'yaws')):
                np.testing.assert_allclose(value, expected[name][step, index], rtol=0,
                                           atol=1e-12, err_msg=f'{name} of {robot} at {step}')


@pytest.mark.parametrize(('parameters', 'expected'), [
    ({'scenario': 'BAD_FILE'}, ['BAD_FILE', 'robots[1].radius', 'must be in (0, 100]']),
    ({'mode': 'fast'}, ['mode', 'fast', 'lockstep, realtime']),
    ({'scenario': 'no_such_scenario'}, ['no_such_scenario', 'no such scenario']),
    ({'observers': "['prvo_run_recorder']"}, ["observers: 'prvo_run_recorder' does not start"]),
    ({'cmd_timeout': '0.0'}, ['cmd_timeout']),
])
def test_bad_input_exits_non_zero_naming_it(children, ros2_executable, tmp_path, parameters,
                                            expected):
    bad_file = tmp_path / 'bad.yaml'
    text = find_scenario('headon2').read_text()
    # The last radius in headon2 is robots[1]'s.
    bad_file.write_text('radius: -0.3'.join(text.rsplit('radius: 0.3', 1)))
    parameters = {name: str(bad_file) if value == 'BAD_FILE' else value
                  for name, value in parameters.items()}
    expected = [str(bad_file) if text == 'BAD_FILE' else text for text in expected]
    sim = start_sim(children, ros2_executable, 'sim', **parameters)
    assert sim.wait(timeout=20.0) == 2
    output = children.output(sim)
    for text in expected:
        assert text in output
    assert 'Traceback' not in output


def loaded_library(process, name):
    """Whether PROCESS has a shared library whose path contains NAME mapped."""
    try:
        with open(f'/proc/{process.pid}/maps') as maps:
            return name in maps.read()
    except OSError:
        return False


@pytest.mark.parametrize('moment', ['importing', 'waiting', 'stepping'])
@pytest.mark.parametrize('signal_name', ['SIGINT', 'SIGTERM'])
def test_shutdown_at_any_moment_is_quiet(probe, children, ros2_executable, moment, signal_name):
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    if moment != 'waiting':
        Planners(probe, HEAD_ON)
    sim = start_sim(children, ros2_executable, 'sim', mode='realtime')
    if moment == 'importing':
        # rclpy's C library is in: the interpreter runs the executable's imports (or later).
        probe.wait_until(lambda: loaded_library(sim, 'librcl'), 30.0, 'rclpy loaded by the sim')
    else:
        status = 'running' if moment == 'stepping' else 'waiting for'
        probe.wait_until(lambda: any(
            s.name == 'prvo_sim' and s.message.startswith(status)
            for array in diagnostics for s in array.status), 30.0, f'the sim {moment}')
    sim.send_signal(getattr(signal, signal_name))
    # Exit 0, or killed by SIGTERM itself before Python has a handler for it.
    assert sim.wait(timeout=15.0) in (0, -signal.SIGTERM)
    output = children.output(sim)
    for bad in ('Traceback', 'FATAL', 'Error', 'KeyboardInterrupt'):
        assert bad not in output


WALKER_HEADON = """\
name: walker_headon
seed: 2
dt: 0.1
duration: 60.0
goal_tolerance: 0.2
robots:
  - name: robot_0
    start: [-4.0, 0.0]
    goal: [4.0, 0.0]
    radius: 0.3
    max_speed: 1.0
  - name: robot_1
    start: [4.0, 0.0]
    radius: 0.3
    max_speed: 1.0
    scripted: {waypoints: [[4.0, 3.0]], speed: 0.5}
"""


def test_scripted_robot_walks_without_cmd_vel_and_is_reported(probe, children, ros2_executable,
                                                              tmp_path):
    scenario = tmp_path / 'walker_headon.yaml'
    scenario.write_text(WALKER_HEADON)
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # Only robot_0 answers. Lockstep must not wait for the scripted robot_1 (a wait would
    # stall the run: the step timeout is an hour).
    planners = Planners(probe, {'robot_0': HEAD_ON['robot_0']})
    sim = start_sim(children, ros2_executable, 'sim', scenario=str(scenario),
                    step_timeout=3600.0, startup_timeout=3600.0)
    steps = 40
    probe.wait_until(lambda: len(planners.steps('robot_1', 'ground_truth')) > steps, 60.0,
                     f'{steps} steps of the scripted robot')
    for step in range(steps + 1):
        walker = odometry_to_measurement(
            planners.ground_truth['robot_1'][round(step * HEADON2.dt * 1e9)])
        # Noise-free: 0.05 m per step up to its one waypoint at (4, 3), whatever robot_0 does.
        np.testing.assert_allclose(walker.position, [4.0, min(0.05 * step, 3.0)], atol=1e-9)
    probe.wait_until(lambda: latest_statuses(diagnostics), 10.0, "the simulator's diagnostics")
    # The run ends here, not at teardown. Killed there mid-run (the probe answers robot_0 at
    # once, so steps come as fast as the CPU allows), it left messages in flight while the
    # probe destroyed its subscriptions: a pytest worker crashed in that teardown twice in CI.
    assert children.interrupt(sim) == 0
    statuses = latest_statuses(diagnostics)
    assert statuses['prvo_sim']['deadline_misses'] == '0'
    assert statuses['prvo_sim/robot_1']['scripted'] == 'true'
    assert statuses['prvo_sim/robot_1']['waypoint'] == '0'
    assert statuses['prvo_sim/robot_1']['deadline_misses'] == '0'
    assert statuses['prvo_sim/robot_0']['scripted'] == 'false'


def test_map_and_world_markers_reach_a_late_subscriber(probe, children, ros2_executable):
    from nav_msgs.msg import OccupancyGrid
    from visualization_msgs.msg import Marker, MarkerArray

    from prvo_msgs_util import MAP, MAP_QOS, WORLD_MARKERS

    sim = start_sim(children, ros2_executable, 'sim', scenario='doorway8')
    # The simulator publishes the map once, at start-up; it waits for planners that never
    # come. Subscribe only once it has published.
    probe.wait_until(lambda: 'simulating doorway8' in children.output(sim), 20.0,
                     'the simulator to start')
    maps = probe.record(OccupancyGrid, MAP, MAP_QOS)
    markers = probe.record(MarkerArray, WORLD_MARKERS, MAP_QOS)
    probe.wait_until(lambda: maps and markers, 10.0, 'the latched /map and world markers')
    (grid,) = maps
    static = load_scenario(find_scenario('doorway8')).static_world
    expected = static.grid
    assert grid.header.frame_id == 'map'
    assert (grid.info.height, grid.info.width) == expected.shape
    assert grid.info.resolution == pytest.approx(expected.resolution)
    assert [grid.info.origin.position.x, grid.info.origin.position.y] == pytest.approx(
        expected.origin.tolist())
    assert np.array_equal(np.array(grid.data, dtype=np.int8).reshape(expected.shape),
                          expected.cells)
    (array,) = markers
    cubes = [marker for marker in array.markers if marker.type == Marker.CUBE]
    assert len(cubes) == len(static.walls) == 6
    assert children.interrupt(sim) == 0
