"""Stand-in for a sim or planner process in runner tests (ROS arguments after the mode ignored).

    fake_child.py run      start a grandchild that ignores SIGINT, then exit on SIGINT
    fake_child.py stubborn ignore SIGINT (only SIGKILL ends it)
    fake_child.py crash    exit at once with code 3

'run' and 'stubborn' print 'ready' once their signal handling is in place.
"""

import signal
import sys

# First thing: a SIGINT during the imports below would otherwise be swallowed by importlib.
if sys.argv[1] == 'run':
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))

import subprocess  # noqa: E402

IGNORING_SLEEPER = ('import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
                    'time.sleep(600)')


def main():
    """Behave as the mode in argv[1] says."""
    mode = sys.argv[1]
    if mode == 'crash':
        return 3
    if mode == 'run':
        # Same process group: only a group-wide SIGKILL can end it once its parent is gone.
        subprocess.Popen([sys.executable, '-c', IGNORING_SLEEPER])
    else:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    print('ready', flush=True)
    while True:
        signal.pause()


if __name__ == '__main__':
    sys.exit(main())
