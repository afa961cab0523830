"""Observers of a simulator: nodes that must subscribe to its output before its first step."""

from rclpy.exceptions import InvalidNamespaceException, InvalidNodeNameException
from rclpy.validate_namespace import validate_namespace
from rclpy.validate_node_name import validate_node_name


def observer_name_fault(name):
    """Return why NAME is not a fully qualified node name ('/node', '/ns/node'), else None."""
    namespace, _, node_name = name.rpartition('/')
    if not name.startswith('/'):
        return f"observers: {name!r} does not start with / (like '/prvo_run_recorder_1234')"
    try:
        validate_namespace(namespace or '/')
        validate_node_name(node_name)
    except (InvalidNamespaceException, InvalidNodeNameException) as error:
        reason = str(error).splitlines()[0]
        return f'observers: {name!r} is not a fully qualified node name: {reason}'
    return None


class ObserverGate:
    """Whether every observer subscribes to every observed topic, and every match is made.

    OBSERVED is a list of (topic, this node's publisher on it). A topic is complete when each
    observer has a subscription on it in the ROS graph and the publisher has matched at least
    as many subscriptions as there are observers.
    """

    def __init__(self, node, observers, observed):
        self._node = node
        self.observers = list(observers)
        self._observed = list(observed)

    def missing(self):
        """Return {observer: [topics it lacks]}; 'unmatched' lists topics not matched yet."""
        missing = {}
        if not self.observers:
            return missing
        for topic, publisher in self._observed:
            subscribers = {f'{info.node_namespace.rstrip("/")}/{info.node_name}'
                           for info in self._node.get_subscriptions_info_by_topic(topic)}
            for observer in self.observers:
                if observer not in subscribers:
                    missing.setdefault(observer, []).append(topic)
            if publisher.get_subscription_count() < len(self.observers):
                missing.setdefault('unmatched', []).append(topic)
        return missing

    @staticmethod
    def describe(missing):
        """Return MISSING (from `missing`) as one line naming every missing topic."""
        return '; '.join(
            f'no subscription matched yet on {", ".join(topics)}' if who == 'unmatched'
            else f'{who} has no subscription on {", ".join(topics)}'
            for who, topics in missing.items())
