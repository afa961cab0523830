"""A runner refuses a ROS domain that strangers (e.g. a killed run's simulator) still use."""

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
