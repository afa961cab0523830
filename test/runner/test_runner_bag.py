"""Every run's rosbag2 bag: read back with rosbags, per-topic counts, one decoded message each."""

import csv
import math
import pathlib

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosgraph_msgs.msg import Clock
from runner_testing import HEADON
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray
import yaml

from prvo_msgs_util import make_diagnostic_array, seconds_to_stamp
from prvo_sim import run_scenario
from prvo_sim.runner.bag import (
    CLOCK_TYPE,
    DIAGNOSTIC_ARRAY_TYPE,
    MARKER_ARRAY_TYPE,
    ODOMETRY_TYPE,
    TWIST_STAMPED_TYPE,
    BagMessages,
    stamp_ns,
)
from prvo_sim.runner.recorder import odometry_behind

ROBOTS = ('robot_0', 'robot_1')
TOPIC_TYPES = {'/clock': CLOCK_TYPE, '/diagnostics': DIAGNOSTIC_ARRAY_TYPE,
               **{f'/{robot}/{leaf}': message_type for robot in ROBOTS
                  for leaf, message_type in (('odom', ODOMETRY_TYPE),
                                             ('ground_truth', ODOMETRY_TYPE),
                                             ('cmd_vel', TWIST_STAMPED_TYPE),
                                             ('prvo_markers', MARKER_ARRAY_TYPE))}}
DELETEALL = 3  # visualization_msgs/Marker.DELETEALL
ARROW = 0


def read_bag(folder):
    """Return {topic: [(log time ns, decoded message)]} of the bag in FOLDER, and its types."""
    messages, types = {}, {}
    with AnyReader([pathlib.Path(folder)]) as reader:
        for connection in reader.connections:
            types[connection.topic] = connection.msgtype
        for connection, timestamp, data in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (timestamp, reader.deserialize(data, connection.msgtype)))
    return messages, types


def csv_steps(path):
    """Return {robot: [(time s, x, y, cmd_vx, cmd_vy)]} of a trajectories.csv, in time order."""
    steps = {}
    with open(path) as csv_file:
        for row in csv.DictReader(csv_file):
            steps.setdefault(row['robot'], []).append(
                (float(row['time']), float(row['x']), float(row['y']),
                 float(row['cmd_vx']) if row['cmd_vx'] else None,
                 float(row['cmd_vy']) if row['cmd_vy'] else None))
    return steps


def stamp_seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def run_inprocess(out, *options):
    code = run_scenario.main([HEADON, '--engine', 'inprocess', '--out', str(out), '--quiet',
                              *options])
    assert code == 0


def test_inprocess_bag_has_every_topic_per_step_and_decodes(tmp_path):
    out = tmp_path / 'out'
    run_inprocess(out, '--no-animation')
    metadata = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())
    information = metadata['rosbag2_bagfile_information']
    assert information['storage_identifier'] == 'mcap'
    assert [path for path in information['relative_file_paths']] == [
        path.name for path in (out / 'bag').glob('*.mcap')]
    messages, types = read_bag(out / 'bag')
    assert types == TOPIC_TYPES
    assert information['message_count'] == sum(len(topic) for topic in messages.values())
    steps = csv_steps(out / 'trajectories.csv')
    step_count = len(steps['robot_0'])
    times = [step[0] for step in steps['robot_0']]
    # One message per step on each of the simulator's topics and each planner's cmd_vel.
    for topic in ('/clock', *(f'/{robot}/{leaf}' for robot in ROBOTS
                              for leaf in ('odom', 'ground_truth', 'cmd_vel'))):
        assert len(messages[topic]) == step_count, topic
    clock = messages['/clock']
    assert [stamp_seconds(message.clock) for _, message in clock] == pytest.approx(times,
                                                                                   abs=1e-9)
    # Logged at sim time, in time order.
    assert [timestamp for timestamp, _ in clock] == [
        message.clock.sec * 10**9 + message.clock.nanosec for _, message in clock]
    for robot in ROBOTS:
        # Ground truth k is the CSV's row k, exactly; odometry is the noisy measurement of it.
        for (_, truth), (time_s, x, y, _, _) in zip(messages[f'/{robot}/ground_truth'],
                                                    steps[robot], strict=True):
            assert stamp_seconds(truth.header.stamp) == pytest.approx(time_s, abs=1e-9)
            assert (truth.pose.pose.position.x, truth.pose.pose.position.y) == (x, y)
        _, odometry = messages[f'/{robot}/odom'][0]
        assert odometry.header.frame_id == 'map'
        assert odometry.child_frame_id == f'{robot}/base_link'
        assert odometry.pose.covariance[0] == pytest.approx(0.05 ** 2)
        # cmd_vel is in the body frame: turned by the ground truth's yaw, the CSV's command.
        _, command = messages[f'/{robot}/cmd_vel'][5]
        _, truth = messages[f'/{robot}/ground_truth'][5]
        orientation = truth.pose.pose.orientation
        yaw = 2.0 * math.atan2(orientation.z, orientation.w)
        body_x, body_y = command.twist.linear.x, command.twist.linear.y
        world = (math.cos(yaw) * body_x - math.sin(yaw) * body_y,
                 math.sin(yaw) * body_x + math.cos(yaw) * body_y)
        assert world == pytest.approx(steps[robot][5][3:], abs=1e-9)
        assert command.header.frame_id == f'{robot}/base_link'
        # The planner's status and markers go out together, a few times per second of sim time.
        planner_statuses = [message for _, message in messages['/diagnostics']
                            if message.status[0].name == f'prvo_planner/{robot}']
        markers = messages[f'/{robot}/prvo_markers']
        assert 2 <= len(markers) == len(planner_statuses) < step_count
        _, first_markers = markers[0]
        assert [marker.action for marker in first_markers.markers[:1]] == [DELETEALL]
        arrow = first_markers.markers[1]
        assert arrow.type == ARROW
        assert (arrow.points[0].x, arrow.points[0].y) == pytest.approx(steps[robot][0][1:3],
                                                                      abs=0.3)
    simulator_statuses = [message for _, message in messages['/diagnostics']
                          if message.status[0].name == 'prvo_sim']
    assert [int(dict((value.key, value.value) for value in message.status[0].values)['step'])
            for message in simulator_statuses] == list(range(step_count))


def test_no_bag_and_no_animation_leave_neither_and_remove_old_ones(tmp_path):
    out = tmp_path / 'out'
    run_inprocess(out)
    assert (out / 'bag' / 'metadata.yaml').exists() and (out / 'trajectories.gif').exists()
    run_inprocess(out, '--no-bag', '--no-animation')
    assert not (out / 'bag').exists()
    assert not (out / 'trajectories.gif').exists()
    assert sorted(path.name for path in out.iterdir()) == [
        'metrics.json', 'trajectories.csv', 'trajectories.png']


@pytest.mark.parametrize('message, message_type', [
    (Clock(clock=seconds_to_stamp(12.3)), CLOCK_TYPE),
    (make_diagnostic_array(7.25, []), DIAGNOSTIC_ARRAY_TYPE),
    (TwistStamped(header=Header(stamp=seconds_to_stamp(1.5))), TWIST_STAMPED_TYPE),
    (Odometry(header=Header(stamp=seconds_to_stamp(1e6 + 0.1))), ODOMETRY_TYPE),
])
def test_stamp_is_read_from_the_serialized_message(message, message_type):
    stamp = message.clock if message_type == CLOCK_TYPE else message.header.stamp
    data = serialize_message(message)
    assert stamp_ns(data, message_type) == stamp.sec * 10**9 + stamp.nanosec
    # Big-endian CDR says so in its encapsulation header.
    swapped = bytes([0, 0, 0, 0]) + stamp.sec.to_bytes(4, 'big') + stamp.nanosec.to_bytes(
        4, 'big')
    assert stamp_ns(swapped, message_type) == stamp.sec * 10**9 + stamp.nanosec


def test_marker_array_stamp_is_its_first_markers():
    markers = MarkerArray(markers=[Marker(header=Header(stamp=seconds_to_stamp(3.5))),
                                   Marker(header=Header(stamp=seconds_to_stamp(9.0)))])
    assert stamp_ns(serialize_message(markers), MARKER_ARRAY_TYPE) == 3_500_000_000
    assert stamp_ns(serialize_message(MarkerArray()), MARKER_ARRAY_TYPE) is None
    assert serialize_message(DiagnosticArray())[:2] == b'\x00\x01'  # little-endian CDR


def odometry_at(step, dt=0.1):
    """Return a serialized Odometry stamped at STEP * DT [s]."""
    return serialize_message(Odometry(header=Header(stamp=seconds_to_stamp(step * dt))))


def test_odometry_gaps_are_found_at_the_end_and_within():
    # t = 1.3 s: a stamp with both seconds and nanoseconds; robot_1 lacks the last step's,
    # robot_2 has none, robot_3 lacks one within.
    steps = range(14)
    received = {'robot_0': [odometry_at(step) for step in steps],
                'robot_1': [odometry_at(step) for step in steps[:-1]],
                'robot_2': [],
                'robot_3': [odometry_at(step) for step in steps if step != 5]}
    last = stamp_ns(received['robot_0'][-1], ODOMETRY_TYPE)
    assert last == 1_300_000_000
    # What the runner waits for before it stops the recorder: each robot's newest one.
    assert odometry_behind(received, last) == ['robot_1', 'robot_2']
    assert odometry_behind(received, last - 100_000_000) == ['robot_2']
    # What the bag then lacks, which the runner reports.
    bag = BagMessages(list(received))
    for name, messages in received.items():
        for data in messages:
            bag.add(f'/{name}/odom', data)
    stamps = [stamp_ns(data, ODOMETRY_TYPE) for data in received['robot_0']]
    assert bag.missing_odometry(list(received), stamps) == [
        ('robot_1', 1, 1_300_000_000), ('robot_2', 14, 0), ('robot_3', 1, 500_000_000)]
