"""Entry point of the `sim` executable: a Ctrl-C while it starts exits quietly.

Importing rclpy, numpy and the node takes a moment; a SIGINT then (a runner stopping a run as it
starts) would end the process with a KeyboardInterrupt traceback. The handler set here holds
until the node's main installs its own, just before rclpy starts.
"""

import os
import signal
import sys


def _exit_quietly(signum, frame):
    # Nothing is running yet that needs cleaning up, and a SystemExit raised here would land
    # inside whatever import runs, which can turn it into an ImportError (a C extension's
    # initialisation, for one): leave at once.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def main(args=None):
    """Run `prvo_sim.sim_node.main`, exiting with 0 on a SIGINT during its imports."""
    signal.signal(signal.SIGINT, _exit_quietly)
    # Imported only now, under the handler: this import is the slow part of starting.
    from prvo_sim import sim_node

    return sim_node.main(args)


if __name__ == '__main__':
    sys.exit(main())
