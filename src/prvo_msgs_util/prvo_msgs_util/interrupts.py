"""Telling a Ctrl-C shutdown apart from a real error in a node's main()."""

import signal


class SigintRecorder:
    """
    Remember that SIGINT arrived, keeping Python's KeyboardInterrupt.

    Install it before ``rclpy.init()``: rclpy's own handler wakes the executor and then calls
    the handler it found, this one. rclpy shuts its context down on another thread, so a
    message take in flight when Ctrl-C lands can fail with a RuntimeError while ``rclpy.ok()``
    is still true; ``received`` says that the failure is the shutdown that was asked for.

    Only the first SIGINT raises: a second one (``ros2 launch`` and the terminal both pass
    Ctrl-C on) would land in the node's teardown and end it with a traceback.
    """

    def __init__(self):
        self.received = False

    def install(self):
        """Make this the process's Python SIGINT handler; return self."""
        signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def _on_sigint(self, signum, frame):
        if self.received:
            return
        self.received = True
        raise KeyboardInterrupt
