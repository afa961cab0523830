"""The running system: simulator and planners as real processes, observed through a probe."""

import math
import os
import signal

from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from scipy.stats import chi2
from visualization_msgs.msg import Marker, MarkerArray

from prvo_msgs_util import CMD_VEL_QOS, MARKER_QOS, ODOM_QOS, make_odometry, stamp_to_seconds
from prvo_sim.runner.session import LOCKSTEP_SYNC, STEP_TIMEOUT

pytestmark = pytest.mark.integration


def _run_until_all_arrived(probe, observer, team, what):
    limit = team.scenario.duration
    probe.wait_until(lambda: observer.all_arrived() or observer.sim_time() >= limit,
                     timeout=120.0, what=what)
    return observer.all_arrived()


def test_headon_both_arrive_without_contact(make_team, observe, probe):
    team = make_team('headon2')
    observer = observe(team)
    team.start_sim()
    team.start_planners()
    assert _run_until_all_arrived(probe, observer, team, 'headon2 to finish'), (
        observer.robot_status)
    assert observer.min_clearance(team.scenario) > 0.0
    assert int(observer.sim_status['contacts']) == 0


def run_crossing(team, observer, probe, seed):
    """Return whether every robot of TEAM (crossing4, lockstep, SEED) arrived in its run.

    The run ends when every robot arrived or the duration ended; the team is left running.
    With the runner's lockstep waits: a step waits for every answer, a plan for every
    neighbour's odometry of its step, however loaded the machine (with the team's 2 s and 1 s,
    a planner starved beside another worker's team could miss one, and the run then differ
    from another of the same seed).
    """
    team.start_sim(seed=seed, step_timeout=STEP_TIMEOUT)
    team.start_planners(**LOCKSTEP_SYNC)
    return _run_until_all_arrived(probe, observer, team, f'crossing4 seed {seed} to finish')


@pytest.fixture(scope='module')
def crossing_seed_1(module_team):
    """Return a crossing4 run of seed 1 (`run_crossing`) and its processes' codes on Ctrl-C.

    Shared by the no-contact test of seed 1 and the reproducibility test (its first run).
    """
    team, observer, probe = module_team('crossing4')
    arrived = run_crossing(team, observer, probe, 1)
    exit_codes = {process.label: team.children.interrupt(process)
                  for process in [team.sim, *team.planners.values()]}
    return team, observer, arrived, exit_codes


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_crossing_with_noise_has_no_contact(request, seed):
    if seed == 1:
        team, observer, arrived, _ = request.getfixturevalue('crossing_seed_1')
    else:
        probe = request.getfixturevalue('probe')
        team = request.getfixturevalue('make_team')('crossing4')
        observer = request.getfixturevalue('observe')(team)
        arrived = run_crossing(team, observer, probe, seed)
    assert arrived, observer.robot_status
    assert observer.min_clearance(team.scenario) > 0.0
    assert int(observer.sim_status['contacts']) == 0


def test_lockstep_is_reproducible(crossing_seed_1, make_team, observe, probe, children):
    # The first run is seed 1's of the no-contact test, stopped with Ctrl-C once it arrived;
    # the second is stopped after 8 s of simulated time.
    _, first_observer, _, exit_codes = crossing_seed_1
    assert set(exit_codes.values()) == {0}, exit_codes
    team = make_team('crossing4')
    observer = observe(team)
    team.start_sim(seed=1, label='sim_again', step_timeout=STEP_TIMEOUT)
    for spec in team.scenario.robots:
        team.start_planner(spec.name, label=f'planner_{spec.name}_again', **LOCKSTEP_SYNC)
    probe.wait_until(lambda: observer.sim_time() >= 8.0, timeout=90.0,
                     what='8 s of simulated time')
    for process in [team.sim, *team.planners.values()]:
        assert children.interrupt(process) == 0
    runs = [first_observer.trajectories(), observer.trajectories()]
    for robot, (stamps, positions) in runs[0].items():
        other_stamps, other_positions = runs[1][robot]
        common = np.intersect1d(stamps[stamps <= 8.0], other_stamps)
        # Reliable keep-last-10 delivery can drop a sample to a loaded probe; the runs
        # themselves are compared wherever both were seen.
        assert common.size >= 40, f'{robot}: only {common.size} common steps'
        first = positions[np.searchsorted(stamps, common)]
        second = other_positions[np.searchsorted(other_stamps, common)]
        np.testing.assert_array_equal(first, second, err_msg=robot)


@pytest.fixture(scope='module')
def realtime_headon(module_team):
    """Return one realtime headon2 team, its probe and what robot_0 published from the start.

    Realtime, as a user inspects a team: a lockstep team can finish its run before a probe has
    subscribed. Started once for the tests of its topics and its markers; the probe records
    robot_0's commands and markers before the simulator starts (markers are built only for a
    subscriber: this one).
    """
    team, _, probe = module_team('headon2')
    commands = probe.record(TwistStamped, '/robot_0/cmd_vel', qos=CMD_VEL_QOS)
    markers = probe.record(MarkerArray, '/robot_0/prvo_markers', qos=MARKER_QOS)
    team.start_sim(mode='realtime')
    team.start_planners()
    return team, probe, commands, markers


def first_recorded(probe, received, predicate, timeout, what):
    """Return the first message in RECEIVED (a `Probe.record` list) satisfying PREDICATE."""
    return probe.wait_until(lambda: next((msg for msg in received if predicate(msg)), None),
                            timeout=timeout, what=what)


def test_topics_are_inspectable(realtime_headon):
    _, probe, commands, _ = realtime_headon
    expected = {
        '/robot_0/odom': 'nav_msgs/msg/Odometry',
        '/robot_0/ground_truth': 'nav_msgs/msg/Odometry',
        '/robot_0/cmd_vel': 'geometry_msgs/msg/TwistStamped',
        '/robot_0/prvo_markers': 'visualization_msgs/msg/MarkerArray',
        '/robot_1/cmd_vel': 'geometry_msgs/msg/TwistStamped',
        '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
        '/clock': 'rosgraph_msgs/msg/Clock',
    }

    def listed():
        # What 'ros2 topic list -t' prints: every topic with its types, and published by the
        # team (the probe's own subscriptions list some of them too).
        topics = dict(probe.node.get_topic_names_and_types())
        return all(expected[name] in topics.get(name, []) and any(
            info.topic_type == expected[name]
            for info in probe.node.get_publishers_info_by_topic(name)) for name in expected)

    probe.wait_until(listed, timeout=20.0, what='every topic to appear with its type')
    command = first_recorded(probe, commands, lambda msg: msg.twist.linear.x > 0.1, 20.0,
                             'a command on /robot_0/cmd_vel heading right')
    # robot_0 starts at x = -4 with its goal at x = +4: it heads right, within its speed limit.
    assert math.hypot(command.twist.linear.x, command.twist.linear.y) <= 1.0 + 1e-9


def test_markers_show_each_neighbour_with_its_confidence_ellipse(realtime_headon):
    _, probe, _, recorded = realtime_headon
    # From 1 s of sim time on, as a probe subscribing to a running team sees them: the first
    # plans can come before robot_1's announcements have reached robot_0.
    markers = first_recorded(
        probe, recorded, lambda msg: len(msg.markers) == 4 and stamp_to_seconds(
            msg.markers[0].header.stamp) >= 1.0, 30.0,
        'markers of robot_0 showing its neighbour, 1 s into the run')
    delete_all, arrow, ellipse, label = markers.markers
    assert delete_all.action == Marker.DELETEALL and arrow.type == Marker.ARROW
    # The size and share robot_1 announced (on its way: reciprocal).
    assert label.type == Marker.TEXT_VIEW_FACING and label.text == 'r 0.30 m, share 0.50'
    assert ellipse.type == Marker.CYLINDER and ellipse.header.frame_id == 'map'
    # The neighbour's disc (radius 0.3) grown by its eta = 0.8 ellipse: the 2-dof chi-square
    # quantile scales the tracked standard deviation, which is the sensors' 0.05 m at the first
    # plan and never above it. How far it has shrunk by the marker the probe receives varies
    # with the machine's load (0.016 m once, in a CI run beside another), so only its growth is
    # bounded from below.
    scale = math.sqrt(chi2.ppf(0.8, df=2))
    assert ellipse.scale.x == pytest.approx(ellipse.scale.y, rel=1e-6)
    assert 2 * 0.3 < ellipse.scale.x <= 2 * (0.3 + scale * 0.05) + 1e-6


def test_killed_planner_is_survived_and_replaced(make_team, observe, probe, children):
    team = make_team('crossing4')
    observer = observe(team)
    team.start_sim(step_timeout=0.3)
    team.start_planners()
    probe.wait_until(lambda: observer.sim_time() >= 2.0, timeout=60.0, what='2 s of sim time')
    os.killpg(team.planners['robot_1'].pid, signal.SIGKILL)
    misses_at_kill = observer.deadline_misses('robot_1')
    probe.wait_until(lambda: observer.deadline_misses('robot_1') >= misses_at_kill + 3,
                     timeout=30.0, what='the simulator to count robot_1 deadline misses')
    assert team.sim.poll() is None
    assert all(team.planners[name].poll() is None for name in ('robot_0', 'robot_2', 'robot_3'))
    time_at_restart = observer.sim_time()
    team.start_planner('robot_1', label='planner_robot_1_restarted')
    probe.wait_for_message(
        TwistStamped, '/robot_1/cmd_vel', lambda msg: msg.header.stamp.sec >= time_at_restart,
        timeout=30.0, qos=CMD_VEL_QOS)
    misses_after_restart = observer.deadline_misses('robot_1')
    sim_time_after_restart = observer.sim_time()
    # Once every robot is at its goal, lockstep runs to the scenario's end within seconds.
    probe.wait_until(lambda: observer.sim_time() >= sim_time_after_restart + 2.0
                     or observer.sim_status.get('finished') == 'true',
                     timeout=60.0, what='2 s more of sim time')
    # Back under control: at most the step in flight during the restart was missed.
    assert observer.deadline_misses('robot_1') <= misses_after_restart + 1


def test_planners_outlive_a_simulator_restart(make_team, observe, probe, children):
    team = make_team('headon2')
    observer = observe(team)
    team.start_planners()
    team.start_sim(label='sim_first')
    probe.wait_until(lambda: observer.sim_time() >= 2.0, timeout=60.0, what='2 s of sim time')
    assert children.interrupt(team.sim) == 0
    observer.sim_status = {}
    observer.robot_status = {}
    team.start_sim(label='sim_second')
    # Sim time starts over; the planners must answer the new stamps for it to advance again.
    probe.wait_until(lambda: 0.0 <= observer.sim_time() and observer.deadline_misses(
        'robot_0') == 0 and observer.sim_time() >= 2.0, timeout=60.0,
        what='the restarted simulator to advance 2 s with the same planners')
    assert all(process.poll() is None for process in team.planners.values())


def test_bad_odometry_is_skipped_and_named(make_team, observe, probe, children):
    team = make_team('headon2')
    observer = observe(team)
    team.start_sim()
    team.start_planners()
    probe.wait_until(lambda: observer.sim_time() >= 1.0, timeout=60.0, what='1 s of sim time')
    publisher = probe.node.create_publisher(Odometry, '/robot_1/odom', ODOM_QOS)
    identity = 0.01 * np.eye(2)

    def odometry(stamp_offset=0.0, position_cov=identity, frame_id='map'):
        return make_odometry(max(observer.sim_time() + stamp_offset, 0.0), [0.0, 0.0],
                             [0.0, 0.0], position_cov, identity, frame_id=frame_id)

    def with_nan():
        message = odometry()
        message.pose.pose.position.x = math.nan
        return message

    # Each bad message, made at the moment it is sent, and the fault its warning must name.
    bad_messages = [
        (with_nan, 'NaN or inf'),
        (lambda: odometry(position_cov=-identity), 'negative x variance'),
        (lambda: odometry(position_cov=[[0.01, 0.05], [0.05, 0.01]]),
         'not positive semi-definite'),
        (lambda: odometry(frame_id='odom'), "expected 'map'"),
        # In lockstep robot_1's planner has the simulator's stamp or the one before; the probe
        # may lag behind both. 0.3 s back stays behind the planner's last stamp, and within the
        # 1 s beyond which it would take the stamp for a restarted simulator, unless the probe
        # lags by 7 steps.
        (lambda: odometry(stamp_offset=-0.3), 'not after'),
    ]
    probe.wait_until(lambda: publisher.get_subscription_count() >= 2, timeout=10.0,
                     what='both planners to see the probe publisher')
    def warned(fault):
        return fault in children.output(team.planners['robot_1'])

    for make_message, fault in bad_messages:
        # The planners keep only the newest odometry: a bad message can be overtaken by the
        # simulator's next one before it is read, so it is sent until its warning shows.
        for _ in range(50):
            publisher.publish(make_message())
            try:
                probe.wait_until(lambda fault=fault: warned(fault), timeout=0.5,
                                 what=f'a warning naming {fault!r}')
                break
            except TimeoutError:
                continue
    assert _run_until_all_arrived(probe, observer, team, 'headon2 to finish after bad input')
    assert all(process.poll() is None for process in [team.sim, *team.planners.values()])
    logs = children.output(team.planners['robot_1'])
    for _, fault in bad_messages:
        assert 'skipping odometry on /robot_1/odom: ' in logs and warned(fault), (
            f'no warning names the fault {fault!r}')


@pytest.mark.parametrize('which', ['sim', 'planner'])
def test_sigint_exits_zero_without_leftovers(make_team, observe, probe, children, which,
                                             live_session_processes):
    team = make_team('headon2')
    observer = observe(team)
    team.start_sim()
    team.start_planners()
    probe.wait_until(lambda: observer.sim_time() >= 0.5, timeout=60.0, what='the team to run')
    process = team.sim if which == 'sim' else team.planners['robot_0']
    assert children.interrupt(process) == 0, children.output(process)
    assert live_session_processes(process.pid) == []
