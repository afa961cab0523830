"""Benchmarks and experiments that run the simulator and the runner; nothing else imports them.

Each module is a command, ``python -m prvo_sim.bench.<name>``:

* ``experiments``: the paper's experiments and the methods table (also the ``experiments``
  console script);
* ``crowds``: crowd circles, random teams and the stall monitor;
* ``engine``: the in-process engine's cost per robot-step, beside the peers;
* ``team``: a ROS team's CPU, memory and deadline misses;
* ``walls``: the wall scenarios beside RVO2 and navground;
* ``calibration``: the beliefs' NEES against the simulator's ground truth.
"""
