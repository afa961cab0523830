"""The runner's recorder: a domain strangers still use is refused; a hung teardown is bounded."""

import threading
import time

from rosgraph_msgs.msg import Clock

from prvo_sim.run_scenario import Recorder


def test_recorder_names_a_stray_simulator_on_its_domain(children, ros2_executable, ros_domain,
                                                        probe):
    children.start('stray_sim', [ros2_executable('prvo_sim', 'sim'), '--ros-args',
                                 '-p', 'scenario:=headon2'])
    # The stray is up once it publishes its clock.
    probe.wait_for_message(Clock, '/clock', timeout=30.0)
    recorder = Recorder(ros_domain, ['robot_0', 'robot_1'])
    try:
        # Returns as soon as discovery shows the stray; the generous limit is for a loaded host.
        failure = recorder.foreign_traffic(30.0)
    finally:
        recorder.close()
    assert failure is not None
    assert f'ROS_DOMAIN_ID {ros_domain} is in use' in failure and '/clock' in failure


def test_recorder_close_gives_up_on_a_hung_dds_teardown(ros_domain):
    # Fast DDS can deadlock deleting a writer; a teardown that never returns must not hang
    # the runner. Stand-in: a destroy_node that blocks until released.
    recorder = Recorder(ros_domain, ['robot_0'])
    released = threading.Event()
    destroy_node = recorder.node.destroy_node
    recorder.node.destroy_node = released.wait
    started = time.monotonic()
    try:
        assert recorder.close(timeout=0.5) is False
        assert time.monotonic() - started < 5.0
    finally:
        released.set()
        destroy_node()
        recorder.context.try_shutdown()


def test_recorder_close_reports_a_clean_teardown(ros_domain):
    recorder = Recorder(ros_domain, ['robot_0'])
    assert recorder.close(timeout=30.0) is True
    assert not recorder.context.ok()
