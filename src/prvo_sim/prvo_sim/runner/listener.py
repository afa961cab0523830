"""The recorder's DDS side: a child process that listens to a run and streams what it hears.

Fast DDS can deadlock while it deletes a DataWriter (ResourceEvent::unregister_timer), and the
rclpy call that deletes it holds the GIL: a process that destroys a participant may never run
Python again, whatever its threads or signal handlers do. So the runner holds no DDS
participant. This process does: it subscribes to the run's topics (serialized, `raw`), sends
every message it takes and, every GRAPH_PERIOD, a snapshot of the ROS graph to the runner over
a socket, and is never torn down: it leaves with `os._exit` when the runner says stop or goes
away, and the runner SIGKILLs it if it does not. What the runner has received is the recording,
whatever happens here.

    python -m prvo_sim.runner.listener SPEC_JSON SOCKET_FD

SPEC_JSON: {"domain_id", "node_name", "topics": [[topic, kind], ...], "matched": [topic, ...]}
with kinds of KINDS; `matched` are the topics whose publisher count the graph snapshot gives.
Messages to the runner (pickled, multiprocessing.connection framing): ('ready', node name),
('messages', [(topic index, bytes), ...]), ('graph', {'publishers': {topic: [node, ...]},
'matched': {topic: publishers matched}}).
"""

import copy
import json
import os
import signal
import sys
import time

GRAPH_PERIOD = 0.5  # wall seconds between snapshots of the ROS graph
SPIN_PERIOD = 0.05  # wall seconds of spinning between two sends of what arrived
RECORDER_QUEUE_DEPTH = 2000  # messages per topic held until this process takes them
# What the graph says of an endpoint whose participant's node names have not arrived yet.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
UNNAMED_NODE = '(a node not named yet)'
# Topics every rclpy node publishes on; publishing there says nothing about a node.
ROS_DEFAULT_TOPICS = ('/rosout', '/parameter_events')


def _message_kinds():
    """Return {kind: (message type, publisher QoS)} of every kind of topic a run records."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import OccupancyGrid, Odometry, Path
    from rosgraph_msgs.msg import Clock
    from visualization_msgs.msg import MarkerArray

    from prvo_msgs_util import (
        CLOCK_QOS,
        CMD_VEL_QOS,
        DIAGNOSTICS_QOS,
        MAP_QOS,
        MARKER_QOS,
        ODOM_QOS,
        PLAN_QOS,
    )

    return {'odometry': (Odometry, ODOM_QOS), 'command': (TwistStamped, CMD_VEL_QOS),
            'diagnostics': (DiagnosticArray, DIAGNOSTICS_QOS), 'clock': (Clock, CLOCK_QOS),
            'markers': (MarkerArray, MARKER_QOS), 'map': (OccupancyGrid, MAP_QOS),
            'plan': (Path, PLAN_QOS)}


KINDS = ('odometry', 'command', 'diagnostics', 'clock', 'markers', 'map', 'plan')


def full_name(namespace, name):
    """Return the node's fully qualified name, or UNNAMED_NODE while discovery lacks it."""
    if name == UNKNOWN_NODE_NAME:
        return UNNAMED_NODE
    return f"{namespace.rstrip('/')}/{name}"


def _deep(qos):
    """Return QOS with a queue of RECORDER_QUEUE_DEPTH (compatible: depth is not matched).

    A lockstep team steps hundreds of times per second; between two spins the messages wait
    in this queue, and a shorter one would drop the oldest.
    """
    deep = copy.copy(qos)
    deep.depth = RECORDER_QUEUE_DEPTH
    return deep


def graph_snapshot(node, matched_subscriptions):
    """Return {'publishers': {topic: [node, ...]}, 'matched': {topic: count}} of NODE's graph."""
    publishers = {}
    for topic, _ in node.get_topic_names_and_types():
        if topic in ROS_DEFAULT_TOPICS:
            continue
        for info in node.get_publishers_info_by_topic(topic):
            publishers.setdefault(topic, []).append(
                full_name(info.node_namespace, info.node_name))
    return {'publishers': publishers,
            'matched': {topic: subscription.get_publisher_count()
                        for topic, subscription in matched_subscriptions.items()}}


def listen(spec, connection):
    """Subscribe as SPEC says, then stream to CONNECTION until told to stop; never returns."""
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions
    from rclpy.task import Future

    from prvo_msgs_util import quiet_subscription_events

    kinds = _message_kinds()
    context = Context()
    rclpy.init(context=context, domain_id=spec['domain_id'],
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(spec['node_name'], context=context)
    executor = EventsExecutor(context=context)
    executor.add_node(node)
    pending = []
    subscriptions = {}
    for index, (topic, kind) in enumerate(spec['topics']):
        message_type, qos = kinds[kind]
        subscriptions[topic] = node.create_subscription(
            message_type, topic, lambda data, index=index: pending.append((index, data)),
            _deep(qos), event_callbacks=quiet_subscription_events(), raw=True)
    matched = {topic: subscriptions[topic] for topic in spec['matched']}
    connection.send(('ready', node.get_fully_qualified_name()))
    never_done = Future()
    next_graph = time.monotonic()
    while True:
        executor.spin_until_future_complete(never_done, timeout_sec=SPIN_PERIOD)
        if pending:
            batch, pending[:] = list(pending), []
            connection.send(('messages', batch))
        now = time.monotonic()
        if now >= next_graph:
            next_graph = now + GRAPH_PERIOD
            connection.send(('graph', graph_snapshot(node, matched)))
        if connection.poll():
            # The only request is to stop: everything that has arrived meanwhile goes first
            # (the runner kills this process if it does not leave soon).
            connection.recv()
            taken = -1
            while taken != len(pending):
                taken = len(pending)
                executor.spin_until_future_complete(never_done, timeout_sec=0.0)
            connection.send(('messages', list(pending)))
            _leave(0)


def _leave(code):
    """Exit without destroying a DDS entity (see the module's docstring)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def main(argv=None):
    """Run the listener of SPEC_JSON on SOCKET_FD (see the module's docstring)."""
    from multiprocessing.connection import Connection

    argv = sys.argv[1:] if argv is None else argv
    spec, descriptor = json.loads(argv[0]), int(argv[1])
    # The runner stops this process; a stray signal just ends it, without DDS teardown.
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, lambda signum, frame: _leave(128 + signum))
    connection = Connection(descriptor)
    try:
        listen(spec, connection)
    except (EOFError, OSError):
        # The runner went away.
        _leave(0)
    except BaseException as error:  # noqa: B036 (anything else: say what, then leave at once)
        print(f'listener: error: {error!r}', file=sys.stderr)
        _leave(1)


if __name__ == '__main__':
    main()
