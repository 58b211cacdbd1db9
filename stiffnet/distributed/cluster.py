"""Where work runs: an existing Dask cluster, a LocalCluster for one job, or in-process."""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterator
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.errors import StiffnetError

if TYPE_CHECKING:  # pragma: no cover
    from distributed import Client

#: Environment variable holding a scheduler address (read by the CLI's ``--scheduler``).
SCHEDULER_ENV = "STIFFNET_SCHEDULER"

#: Environment of LocalCluster workers: one process = one core. Numerical libraries
#: would otherwise each start a thread per core in every worker and oversubscribe.
WORKER_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


#: The shipped housekeeping settings of a job's LocalCluster.
LOCAL_CLUSTER_CONFIG = "distributed/local_cluster.yaml"


class LocalClusterSettings(BaseModel):
    """Dask's periodic housekeeping in a LocalCluster started for one job
    (``configs/distributed/local_cluster.yaml``): a job's cluster has no dashboard, and its
    tasks are queued on the scheduler in the order given, so these cost CPU for nothing."""

    model_config = ConfigDict(extra="forbid")

    #: Dask's statistical profiler on the workers (a stack sample every 10 ms).
    profile: bool = False
    #: Seconds between the event loops' blocked-loop checks (Dask: 0.02).
    tick_interval_s: float = Field(1.0, gt=0.0, le=60.0)
    #: Work stealing between workers (Dask: on, every 0.1 s).
    work_stealing: bool = False
    #: Seconds between the servers' CPU and memory samples for the dashboard (Dask: 0.5).
    system_monitor_interval_s: float = Field(5.0, gt=0.0, le=600.0)

    def dask_config(self) -> dict[str, Any]:
        """These settings as Dask config keys."""
        return {
            "distributed.worker.profile.enabled": self.profile,
            "distributed.admin.tick.interval": f"{self.tick_interval_s}s",
            "distributed.scheduler.work-stealing": self.work_stealing,
            "distributed.admin.system-monitor.interval": f"{self.system_monitor_interval_s}s",
        }


@lru_cache(maxsize=1)
def local_cluster_settings() -> LocalClusterSettings:
    """The shipped settings: ``configs/distributed/local_cluster.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(LocalClusterSettings, LOCAL_CLUSTER_CONFIG)


def import_distributed() -> Any:
    """Import ``distributed`` or fail with a one-line hint about the ``dask`` extra."""
    try:
        import distributed
    except ImportError:
        raise StiffnetError(
            "--scheduler/--workers need Dask: pip install 'stiffnet[dask]'"
        ) from None
    return distributed


#: A Dask scheduler address: tcp|tls|ucx://host[:port], or host:port.
SCHEDULER_ADDRESS = re.compile(
    r"^(?:(?:tcp|tls|ucx)://(?:[\w.\-]+|\[[0-9a-fA-F:]+\])(?::\d{1,5})?"
    r"|(?:[\w.\-]+|\[[0-9a-fA-F:]+\]):\d{1,5})/?$"
)


def check_target(scheduler: str | None, workers: int | None) -> None:
    """Validate a ``scheduler``/``workers`` pair (both set, or a bad count, is an error)."""
    if scheduler is not None and workers is not None:
        raise StiffnetError(f"use either --scheduler (or {SCHEDULER_ENV}) or --workers, not both")
    from stiffnet.inputs import bounded_count, max_local_workers, one_line

    bounded_count(workers, "--workers", 1, max_local_workers())
    if scheduler is not None and not scheduler.strip():
        raise StiffnetError("--scheduler is empty: give a Dask scheduler address")
    if scheduler is not None and not SCHEDULER_ADDRESS.match(scheduler.strip()):
        raise StiffnetError(
            f"--scheduler {one_line(scheduler, 80)!r} is not a Dask scheduler address "
            "(tcp://host:port, tls://host:port or host:port)"
        )


@contextlib.contextmanager
def dask_client(
    scheduler: str | None = None, workers: int | None = None
) -> Iterator[Client | None]:
    """A Dask client for the job, or ``None`` for in-process work.

    Parameters
    ----------
    scheduler
        Address of a running Dask scheduler (``tcp://host:8786``); the client connects
        to it and the cluster is left running afterwards.
    workers
        Start a LocalCluster of this many single-threaded worker processes on
        127.0.0.1 for the job and close it afterwards.

    With both ``None`` the job runs in-process and Dask is not imported. The
    ``STIFFNET_SCHEDULER`` variable is read by the CLI (``--scheduler``), not here, so
    library calls never change where they run behind the caller's back.
    """
    check_target(scheduler, workers)
    if scheduler is None and workers is None:
        yield None
        return
    distributed = import_distributed()
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise StiffnetError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            yield client
        return
    cluster = local_cluster(workers)
    with cluster, distributed.Client(cluster) as client:
        yield client


def local_cluster(workers: int) -> Any:
    """A LocalCluster of ``workers`` single-threaded processes on 127.0.0.1, no dashboard.

    The caller closes it (it is a context manager). Workers get one thread for
    OpenMP/BLAS/numba (:data:`WORKER_ENV`): with one task per process, more threads
    would only fight over the same cores. Dask's housekeeping is set by
    :func:`local_cluster_settings` (the scheduler reads it when it starts; each nanny gives it
    to every worker it starts or restarts).
    """
    distributed = import_distributed()
    import dask

    config = local_cluster_settings().dask_config()
    with dask.config.set(config):
        return distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            host="127.0.0.1",
            env=WORKER_ENV,
            silence_logs=logging.ERROR,
            # no dashboard; the scheduler's small HTTP server (health checks) on a free
            # local port, not on 8787 where another user's cluster may be
            scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
            # each nanny hands these to every worker it (re)starts, whenever that is
            config=config,
        )
