"""Run a scenario end to end: the simulator and one planner per robot, recorded and measured.

    run_scenario SCENARIO.yaml [--out DIR] [--method M] [--eta ETA] [--seed S] [--seeds N]

The children are launch-free subprocesses, each in a session of its own, on a ROS_DOMAIN_ID the
run holds exclusively (--domain-id, else an exported ROS_DOMAIN_ID, else the first free one),
with localhost-only discovery; they never outlive the runner. The planners start first; the
simulator starts once the recorder hears every planner, and steps once the recorder listens to
it. The runner ends the run when every robot has arrived (and stayed), when the simulator
reports `finished`, when a child dies, when a process it did not start publishes on the domain
or at a wall-clock limit, writes metrics.json, trajectories.csv, the plot, the bag and the
animation from what it recorded, then shuts every child down (SIGINT, then SIGKILL) whatever
happened. The implementation is in prvo_sim.runner (docs/interfaces.md, "The runner: how a
run ends"); this module is its entry point.

Exit codes: 0 the run completed (collisions are a result, not an error), 1 a child failed, the
run timed out or was interfered with, 2 refused (nothing was started, nothing written),
128 + signal number when interrupted (SIGINT, SIGTERM, SIGHUP).
"""

import sys

from prvo_sim.runner.command_line import (  # noqa: F401 (the runner's public names)
    UsageError,
    _ArgumentParser,
    build_parser,
    check_writable,
    main,
    parse_arguments,
    run,
    run_interruptibly,
)
from prvo_sim.runner.domain import (  # noqa: F401
    DOMAIN_IDS,
    DOMAIN_LOCK_DIR,
    DomainRefusedError,
    claimed_domain,
)
from prvo_sim.runner.outputs import (  # noqa: F401
    outcome,
    plot_title,
    print_summary,
    write_outputs,
    write_summary,
    write_trajectories_csv,
)
from prvo_sim.runner.processes import (  # noqa: F401
    Children,
    RunInterruptedError,
    package_command,
)
from prvo_sim.runner.recorder import Recorder, foreign_participants, recording_gaps  # noqa: F401
from prvo_sim.runner.session import (  # noqa: F401
    DEFAULT_ETA,
    METHODS,
    RunSpec,
    planner_parameters,
    ros_parameter,
    run_eta,
    run_once,
)

if __name__ == '__main__':
    sys.exit(main())
