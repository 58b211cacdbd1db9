"""Running independent tasks in-process, on a LocalCluster, or on an existing Dask
cluster (``dask.distributed``). Dask is optional (the ``dask`` extra): nothing here
imports it at module level. This package knows nothing of what the tasks compute: the
callers (dataset generation, campaign simulation, diagnosis, ``serving.batch_prediction``) bring
their task functions and, for compiled kernels, their thread limit.

- :mod:`stiffnet.distributed.cluster`: where work runs (``scheduler`` / ``workers``).
- :mod:`stiffnet.distributed.tasks`: :func:`map_tasks` / :func:`run_tasks`,
  order-preserving, retried.
"""

from stiffnet.distributed.cluster import SCHEDULER_ENV, dask_client
from stiffnet.distributed.tasks import TaskReport, map_tasks, run_tasks

__all__ = ["SCHEDULER_ENV", "TaskReport", "dask_client", "map_tasks", "run_tasks"]
