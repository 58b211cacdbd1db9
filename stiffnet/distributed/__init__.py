"""Running stiffnet jobs on Dask (``dask.distributed``): in-process, on a LocalCluster, or
on an existing cluster. Dask is optional (the ``dask`` extra): nothing here imports it
at module level.

- :mod:`stiffnet.distributed.cluster`: where work runs (``scheduler`` / ``workers``).
- :mod:`stiffnet.distributed.tasks`: :func:`map_tasks`, order-preserving, retried.
- :mod:`stiffnet.distributed.batch`: ``predict-batch`` (recordings → one Parquet table).
"""

from stiffnet.distributed.cluster import SCHEDULER_ENV, dask_client
from stiffnet.distributed.tasks import TaskReport, map_tasks, run_tasks

__all__ = ["SCHEDULER_ENV", "TaskReport", "dask_client", "map_tasks", "run_tasks"]
