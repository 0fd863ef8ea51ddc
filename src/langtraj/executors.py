"""Where corpus shards run (synthesis, labeling): the extension point between a job and a compute engine.

An executor maps a picklable function over independent items and yields the results as they finish.
`process` (the default) is a local process pool; `ray` hands each item to a Ray cluster as a task
(docs/design.md, 'Scale-out'), so one command scales from a laptop to many nodes. libsumo keeps one
simulation per process, so every engine must run one item per process at a time. Each process gets its share of
the machine's cores for its math libraries (`share_cores`): two workers each spinning up a thread per core ran a
suite six times slower than one (docs/benchmarks.md, 'Suite workers').
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, ClassVar

from langtraj.errors import LangTrajError
from langtraj.registry import Registry

OnLost = Callable[[Any, BaseException], Any] | None
"""What an item whose worker died yields instead of its result (`ShardExecutor.map`)."""


class ShardExecutor(ABC):
    """Runs `fn` over `items` with at most `workers` at a time; yields results in completion order. Where an engine
    can tell which item a dead worker was running, it yields `on_lost(item, error)` for it and goes on (when given);
    else the error ends the map, and the caller counts what did not finish as lost."""

    name: ClassVar[str]

    @abstractmethod
    def map(
        self,
        fn: Callable[[Any], Any],
        items: Sequence[Any],
        workers: int,
        on_lost: OnLost = None,
    ) -> Iterator[Any]: ...


EXECUTORS: Registry[ShardExecutor] = Registry("executor")

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
"""The variables math libraries read for their thread count when they load."""


def share_cores(workers: int) -> int:
    """Limit this process's math threads to its share of the cores when `workers` processes run at once (a pool
    worker's initializer); a count the user set in the environment wins. Returns the threads it now has."""
    threads = max(1, (os.cpu_count() or 1) // max(1, workers))
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, str(threads))
    threads = int(os.environ["OMP_NUM_THREADS"])
    torch = sys.modules.get("torch")  # already loaded (an import at spawn): it read the variables too early
    if torch is not None:
        torch.set_num_threads(threads)
    return threads


@EXECUTORS.register
class ProcessExecutor(ShardExecutor):
    """In this process when `workers` is 1, else a pool of fresh (spawned) processes on this machine."""

    name = "process"

    def map(
        self,
        fn: Callable[[Any], Any],
        items: Sequence[Any],
        workers: int,
        on_lost: OnLost = None,
    ) -> Iterator[Any]:
        """A dead process breaks the whole pool (`BrokenProcessPool`): the error ends the map, whatever `on_lost`."""
        if workers <= 1 or len(items) <= 1:
            yield from (fn(item) for item in items)
            return
        context = multiprocessing.get_context("spawn")  # libsumo keeps global state: fresh processes only
        pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=context, initializer=share_cores, initargs=(workers,)
        )
        try:
            for future in as_completed([pool.submit(fn, item) for item in items]):
                yield future.result()
        finally:  # on an error or Ctrl-C, shards not yet started are dropped rather than run
            pool.shutdown(wait=True, cancel_futures=True)


@EXECUTORS.register
class RayExecutor(ShardExecutor):
    """Tasks on a Ray cluster: the one at `RAY_ADDRESS` when set, else a local one with `workers` CPUs.

    Every node needs LangTraj installed (SUMO comes with it from PyPI). Each task asks for one CPU, so
    Ray runs as many shards at once as the cluster has CPUs. A local cluster's workers get this process's import
    path (a planner module found in the working directory, `suites.config.load_planner`). A task whose worker dies
    is lost alone (`on_lost`); the others run on.
    """

    name = "ray"

    def map(
        self,
        fn: Callable[[Any], Any],
        items: Sequence[Any],
        workers: int,
        on_lost: OnLost = None,
    ) -> Iterator[Any]:
        try:
            import ray
        except ImportError:
            raise LangTrajError("the ray executor needs Ray: pip install 'langtraj[ray]'") from None
        if not ray.is_initialized():
            address = os.environ.get("RAY_ADDRESS")
            local: dict[str, Any] = {}
            if not address:
                path = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
                local = {"num_cpus": workers, "runtime_env": {"env_vars": {"PYTHONPATH": path}}}
            ray.init(address=address, include_dashboard=False, log_to_driver=False, **local)
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = {remote.remote(item): item for item in items}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            item = pending.pop(done[0])
            try:
                result = ray.get(done[0])
            except ray.exceptions.RayError as error:  # the worker died (or fn raised): this item alone is lost
                if on_lost is None:
                    raise
                result = on_lost(item, error)
            yield result
