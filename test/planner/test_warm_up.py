"""A planner's warm-up loads every compiled kernel its first plans need (docs/interfaces.md)."""

import subprocess

# A fresh process: an agent with the planner node's defaults (the certified bound), warmed up as
# the node warms it before spinning. The kernels are numba functions compiled once by setup and
# loaded from its cache on their module's import: after the warm-up no plan imports one.
PROBE = """
import sys
from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.parameters import DEFAULTS, planner_config_from
agent = PlannerAgent('self', planner_config_from({}), AgentSettings.from_parameters(DEFAULTS))
before = sorted(m for m in sys.modules if m.startswith('prvo_planner.core.'))
agent.warm_up()
kernels = ('prvo_planner.core.ray_search', 'prvo_planner.core.certificate_kernels',
           'prvo_planner.core.choice_kernels', 'prvo_planner.core.moment_kernels')
print(sorted(m for m in kernels if m in sys.modules and m not in before))
"""


def test_the_warm_up_loads_the_ray_search_the_moments_the_certificate_and_the_choice(
        python_executable):
    output = subprocess.run([python_executable, '-c', PROBE], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == str(['prvo_planner.core.certificate_kernels',
                                  'prvo_planner.core.choice_kernels',
                                  'prvo_planner.core.moment_kernels',
                                  'prvo_planner.core.ray_search'])


# A fresh planner node (the node's defaults, no map yet), warmed up as `warmed_up_planner` does:
# its warm-up loads the walls' kernels too, since a map can come at any time.
NODE_PROBE = """
import sys
import rclpy
from prvo_planner.planner_node import PlannerNode
rclpy.init(args=['--ros-args', '-r', '__ns:=/robot_0', '-p', 'neighbors:=[""]'])
node = PlannerNode()
before = 'prvo_planner.core.wall_kernels' in sys.modules
node.warm_up()
print(before, 'prvo_planner.core.wall_kernels' in sys.modules)
node.destroy_node()
rclpy.try_shutdown()
"""


def test_the_planner_node_s_warm_up_loads_the_walls_kernels(python_executable, ros_env):
    output = subprocess.run([python_executable, '-c', NODE_PROBE], capture_output=True,
                            text=True, check=True, env=ros_env).stdout
    assert output.strip().splitlines()[-1] == 'False True'
