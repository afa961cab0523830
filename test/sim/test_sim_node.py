"""The `sim` executable as a real process, driven by a probe-side stand-in for the planners."""

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
    NaN command instead. FRAMES gives a robot's command frame (default map). Odometry and
    ground truth are recorded per robot, keyed by stamp.
    """

    def __init__(self, probe, commands, rogue=(), answer_until_step=None, frames=None):
        self._probe = probe
        self._commands = commands
        self._frames = frames or {}
        self._rogue = rogue
        self._answer_until_ns = (
            None if answer_until_step is None
            else round(answer_until_step * HEADON2.dt * 1e9))
        self.lock = threading.Lock()
        self.odometry = {robot: {} for robot in ROBOTS}
        self.ground_truth = {robot: {} for robot in ROBOTS}
        self.arrival_times = {robot: {} for robot in ROBOTS}
        self._subscriptions = []
        self._publishers = {}
        for robot in ROBOTS:
            self._publishers[robot] = probe.node.create_publisher(
                TwistStamped, f'/{robot}/cmd_vel', CMD_VEL_QOS)
            self._subscriptions.append(probe.node.create_subscription(
                Odometry, f'/{robot}/odom',
                lambda msg, robot=robot: self._on_odometry(robot, msg), ODOM_QOS))
            self._subscriptions.append(probe.node.create_subscription(
                Odometry, f'/{robot}/ground_truth',
                lambda msg, robot=robot: self._keep(self.ground_truth[robot], msg), ODOM_QOS))

    def _keep(self, by_stamp, msg):
        with self.lock:
            by_stamp.setdefault(stamp_ns(msg.header.stamp), msg)

    def _on_odometry(self, robot, msg):
        stamp = stamp_ns(msg.header.stamp)
        with self.lock:
            self.arrival_times[robot].setdefault(stamp, time.monotonic())
        self._keep(self.odometry[robot], msg)
        if self._answer_until_ns is not None and stamp > self._answer_until_ns:
            return
        if robot in self._rogue:
            velocity = (float('nan'), 0.0)
        elif robot in self._commands:
            velocity = self._commands[robot]
        else:
            return
        answer = TwistStamped(twist=make_twist(velocity))
        answer.header.stamp = msg.header.stamp
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
    assert max(stamp_ns(message.clock) for message in clock) >= last_step_ns
    statuses = latest_statuses(diagnostics)
    assert statuses['prvo_sim']['deadline_misses'] == '0'
    assert statuses['prvo_sim']['mode'] == 'lockstep'
    assert int(statuses['prvo_sim']['contacts']) >= 1


def test_silent_robot_times_out_and_bad_command_is_skipped(probe, children, ros2_executable):
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # robot_0 answers every odometry; robot_1 only ever sends NaN, which must not count.
    planners = Planners(probe, {'robot_0': HEAD_ON['robot_0']}, rogue=('robot_1',))
    step_timeout = 0.5
    # The first step waits longer: the probe's subscriptions may match after t_0 went out, and
    # robot_0 answers the re-sent t_0.
    sim = start_sim(children, ros2_executable, 'sim', step_timeout=step_timeout,
                    startup_timeout=3.0)

    def stepped_four_times():
        return int(latest_statuses(diagnostics).get('prvo_sim', {}).get('step', 0)) >= 4
    probe.wait_until(stepped_four_times, 20.0, 'four steps')
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
        arrivals = [received[round(k * HEADON2.dt * 1e9)] for k in range(1, step + 1)
                    if round(k * HEADON2.dt * 1e9) in received]
    assert len(arrivals) >= 2
    # Each step waited for robot_1 until the timeout (less a little receive jitter).
    assert min(np.diff(arrivals)) > 0.8 * step_timeout
    # robot_0's last good command stands: it keeps moving at its commanded speed.
    x = float(statuses['prvo_sim/robot_0']['x'])
    assert x == pytest.approx(-4.0 + step * HEADON2.dt, abs=0.05)
    assert children.interrupt(sim) == 0


def test_realtime_steps_on_the_wall_clock(probe, children, ros2_executable):
    diagnostics = probe.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    # robot_1 starts facing its goal at -x: "forward" in its base_link is -x in the world.
    planners = Planners(probe, {'robot_1': (1.0, 0.0)}, frames={'robot_1': 'robot_1/base_link'})
    # robot_0 never answers: the first step waits startup_timeout for it, then the timer runs.
    sim = start_sim(children, ros2_executable, 'sim', mode='realtime', rate=20.0,
                    startup_timeout=1.0)

    def stepped(count):
        return int(latest_statuses(diagnostics).get('prvo_sim', {}).get('step', 0)) >= count
    probe.wait_until(lambda: stepped(10), 20.0, 'ten realtime steps')
    statuses = latest_statuses(diagnostics)
    assert children.interrupt(sim) == 0

    step = int(statuses['prvo_sim']['step'])
    assert statuses['prvo_sim']['mode'] == 'realtime'
    # robot_0 never answers: every tick is a deadline miss for it, not for robot_1.
    assert statuses['prvo_sim/robot_0']['deadline_misses'] == str(step)
    misses = int(statuses['prvo_sim/robot_1']['deadline_misses'])
    assert misses < step
    # robot_1 moves at 1 m/s on every step it answered in time, and on a late one too once it
    # has a command to reuse; only the steps before its first command leave it standing (a
    # loaded host can delay the probe's first answers).
    travelled = 4.0 - float(statuses['prvo_sim/robot_1']['x'])
    tolerance = 5 * 0.05 * HEADON2.dt * np.sqrt(step)
    assert (step - misses) * HEADON2.dt - tolerance <= travelled <= step * HEADON2.dt + tolerance
    with planners.lock:
        arrivals = sorted(planners.arrival_times['robot_1'].values())
    # 20 Hz wall rate: ticks 50 ms apart on average (not lockstep's as-fast-as-answered).
    assert np.mean(np.diff(arrivals[1:])) == pytest.approx(0.05, rel=0.3)


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
    ({'scenario': 'BAD_FILE'}, ['BAD_FILE', 'robots[1].radius', 'must be > 0']),
    ({'mode': 'fast'}, ['mode', 'fast', 'lockstep, realtime']),
    ({'scenario': 'no_such_scenario'}, ['no_such_scenario', 'no such scenario']),
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
