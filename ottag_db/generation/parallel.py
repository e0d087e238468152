"""Run independent batches of work in this process or on Dask (``dask.distributed``).

:func:`open_workers` gives a :class:`BatchRunner`: in-process for one job, a local Dask cluster
of ``jobs`` worker processes (one thread each) for more, or an existing cluster reached at a
scheduler address. Results come back in the main process one batch at a time, as they finish;
callers that need them in input order keep them by index (so the output never depends on the
workers). Dask is imported only when a cluster is used: ``import ottag_db.generation.parallel``
stays light.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

from ottag_db.errors import ClusterError, UsageError

__all__ = ["BatchRunner", "Workers", "open_workers"]

_T = TypeVar("_T")
_R = TypeVar("_R")

#: Seconds to wait for an existing scheduler before giving up.
_CONNECT_TIMEOUT = 15


@dataclass(frozen=True)
class Workers:
    """Where batches run.

    - ``jobs``: worker processes of a local cluster (1: in this process, no Dask);
    - ``scheduler``: address of an existing Dask scheduler (``tcp://host:8786``); when set,
      ``jobs`` is ignored and the cluster's workers do the work.
    """

    jobs: int = 1
    scheduler: str | None = None

    @property
    def in_process(self) -> bool:
        """True when batches run in this process (one job and no scheduler)."""
        return self.scheduler is None and self.jobs <= 1


class BatchRunner:
    """Runs ``fn`` over batches in this process or on a Dask client (see :func:`open_workers`)."""

    def __init__(self, client: Any | None):
        self._client = client

    @property
    def distributed(self) -> bool:
        """True when batches go to Dask workers."""
        return self._client is not None

    def run(
        self,
        fn: Callable[[_T], _R],
        items: Sequence[_T],
        on_result: Callable[[int, _R], None],
    ) -> None:
        """Call ``fn`` on every item and ``on_result(index, result)`` in this process as each finishes.

        In-process, items run in order. On Dask they are all submitted at once and
        ``on_result`` sees them in completion order (any order); an exception in ``fn`` or in
        ``on_result`` cancels the batches not yet finished and propagates.

        Parameters
        ----------
        fn : callable
            A picklable module-level function of one item (it runs in worker processes).
        items : sequence
            The batches.
        on_result : callable
            ``on_result(index, result)`` with the index of the item in ``items``.
        """
        if self._client is None:
            for i, item in enumerate(items):
                on_result(i, fn(item))
            return
        from distributed import as_completed

        futures = [self._client.submit(fn, item, pure=False) for item in items]
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for fut in as_completed(futures, loop=self._client.loop):  # type: ignore[no-untyped-call]
                on_result(index[fut.key], fut.result())
        finally:
            self._client.cancel([f for f in futures if not f.done()])


@contextmanager
def open_workers(workers: Workers) -> Iterator[BatchRunner]:
    """A :class:`BatchRunner` for ``workers``; a local cluster is shut down on exit.

    Parameters
    ----------
    workers : Workers
        One job (in this process), ``jobs`` local Dask worker processes with one thread
        each, or an existing scheduler's address.

    Yields
    ------
    BatchRunner
        Runs batches there.

    Raises
    ------
    UsageError
        For ``jobs < 1``.
    ClusterError
        When the scheduler cannot be reached.
    """
    if workers.jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {workers.jobs}")
    if workers.in_process:
        yield BatchRunner(None)
        return
    from distributed import Client, LocalCluster

    if workers.scheduler is not None:
        try:
            client = Client(workers.scheduler, timeout=_CONNECT_TIMEOUT, set_as_default=False)  # type: ignore[no-untyped-call]
        except (OSError, TimeoutError, ValueError) as exc:
            raise ClusterError(
                f"cannot reach the Dask scheduler at {workers.scheduler} ({exc}); start one with "
                "`dask scheduler` and workers with `dask worker ADDRESS --nthreads 1` (ottag-db installed), "
                "or drop --scheduler to use local processes"
            ) from exc
        with client:
            yield BatchRunner(client)
        return
    # Worker errors reach the caller as exceptions (one line from the CLI); Dask's own log
    # lines (a failed task's traceback, a heartbeat that races the cluster's shutdown) are not
    # for the user.
    cluster = LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=workers.jobs,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.CRITICAL,
    )
    with cluster, Client(cluster, set_as_default=False) as client:  # type: ignore[no-untyped-call]
        yield BatchRunner(client)
