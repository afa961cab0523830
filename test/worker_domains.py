"""The ROS_DOMAIN_IDs a pytest process takes its domains from (the fixtures and free_domain)."""

import os

from prvo_sim.run_scenario import DOMAIN_IDS


def worker_domain_ids():
    """Return the range of ROS_DOMAIN_IDs this pytest process takes its domains from.

    Under pytest-xdist (./run.sh test runs several workers) each worker has a contiguous share
    of DOMAIN_IDS of its own, so two workers never search for a free domain in the same place;
    the claims (file locks) keep every domain exclusive in any case. Alone: all of DOMAIN_IDS.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')  # 'gw0', 'gw1', ...
    count = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1'))
    if not worker.startswith('gw') or count < 2:
        return DOMAIN_IDS
    share = len(DOMAIN_IDS) // count
    start = DOMAIN_IDS.start + int(worker[2:]) * share
    return range(start, start + share)
