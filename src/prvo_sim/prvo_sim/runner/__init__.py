"""The scenario runner (`run_scenario`, `prvo-run`), in modules.

command_line: options, the domain claim and the exit code; session: one run; processes: the
children and their watchdog; domain: exclusive ROS_DOMAIN_ID claims; recorder: the node that
records a run and watches its domain; outputs: the results written and printed.
"""
