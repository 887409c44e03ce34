"""Executors behind one interface: a ``concurrent.futures.Executor`` from a registry.

* ``inprocess``: runs each task when it is submitted (debugging, tests, tiny sweeps);
* ``process``: a local process pool (default: all cores); its workers exit on their own when
  the sweep process dies (even by ``kill -9``), see :func:`exit_with_parent`;
* ``dask-local``: a ``dask.distributed.LocalCluster`` on this machine (its workers write
  their own parts, like the process pool's);
* ``dask``: an existing Dask scheduler (``--scheduler tcp://HOST:PORT``; dask-jobqueue
  clusters on SLURM/PBS expose one too). Its workers may be on other hosts: they send each
  part back as bytes, and policy modules given as ``module:Class`` are uploaded to them
  (:func:`ship_modules`).

Dask is an optional extra (``pip install 'skymule[dask]'``) and is imported only when asked for.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
import zipfile
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

from skymule.errors import SkymuleError
from skymule.registry import Registry


class InProcessExecutor(Executor):
    """Runs every task at submit time, in this process."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


def default_workers() -> int:
    return os.cpu_count() or 1


@contextmanager
def _inprocess(
    workers: int | None, scheduler: str | None, warm: tuple[str, ...] = ()
) -> Iterator[Executor]:
    with InProcessExecutor() as executor:
        yield executor


#: How often a worker checks that its parent is alive [s].
PARENT_POLL_S = 1.0


def _watch_parent(parent_pid: int, poll_s: float) -> None:
    while True:
        time.sleep(poll_s)
        if os.getppid() != parent_pid:  # re-parented: the sweep process is gone
            os._exit(1)


def exit_with_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> None:
    """Worker initializer: a daemon thread ends this process once ``parent_pid`` has died.

    Polling the parent pid works on every POSIX system and, unlike Linux's
    ``PR_SET_PDEATHSIG``, does not fire when the thread that started the worker ends.
    """
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(
        target=_watch_parent, args=(parent_pid, poll_s), daemon=True, name="skymule-parent"
    ).start()


def start_worker(parent_pid: int, modules: tuple[str, ...]) -> None:
    """Process-pool worker initializer: exit with the parent, then import ``modules``.

    The imports (about a second of CPU for a sweep's engine, pandas and pyarrow) then happen
    while the parent is still planning the first chunk, not after it has sent one.
    """
    exit_with_parent(parent_pid)
    for module in modules:
        importlib.import_module(module)


@contextmanager
def _process(
    workers: int | None, scheduler: str | None, warm: tuple[str, ...] = ()
) -> Iterator[Executor]:
    context = multiprocessing.get_context("spawn")
    others = set(multiprocessing.active_children())
    with ProcessPoolExecutor(
        workers or default_workers(),
        mp_context=context,
        initializer=start_worker,
        initargs=(os.getpid(), warm),
    ) as executor:
        # A spawn pool starts a worker at each submit until it has them all: start them all
        # now, deaf to Ctrl-C for good (an ignored SIGINT is inherited)
        with _workers_deaf_to_ctrl_c():
            for _ in range(workers or default_workers()):
                executor.submit(os.getpid)
        try:
            yield executor
        except KeyboardInterrupt:
            _stop_workers(set(multiprocessing.active_children()) - others)
            raise


def _stop_workers(workers: set[Any]) -> None:
    """Ctrl-C or SIGTERM: end the pool's workers at once, in silence (SIGTERM, whose default
    action runs no Python). A worker interrupted by SIGINT itself prints tracebacks: of its
    wait for work, of its imports, or from inside a compile (numba's LLVM callbacks report an
    interrupt as "Exception ignored"); the chunk it ran is not stored (a part is written
    under a temporary name, which the next sweep on the folder removes) and runs again on
    resume."""
    for worker in workers:
        worker.terminate()
    for worker in workers:
        worker.join(timeout=10)


class DaskExecutor(Executor):
    """A Dask client as an Executor that also knows its cluster.

    ``local``: the workers run on this machine (a ``LocalCluster``) and see its files.
    """

    def __init__(self, client: Any, local: bool) -> None:
        self.client = client
        self.local = local
        self._executor: Executor = client.get_executor(pure=False)

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self._executor.submit(fn, *args, **kwargs)

    def slots(self) -> int:
        """Threads over all the cluster's workers now (at least 1)."""
        return max(1, sum(self.client.nthreads().values()))


def executor_slots(executor: Executor, workers: int | None) -> int:
    """Tasks the executor runs at once: a Dask cluster's threads, else ``workers`` (all
    cores by default)."""
    if isinstance(executor, DaskExecutor):
        return executor.slots()
    return workers or default_workers()


def sees_local_files(executor: Executor) -> bool:
    """True when the executor's workers run on this machine (and can write the sweep folder)."""
    return not isinstance(executor, DaskExecutor) or executor.local


def share(executor: Executor, value: Any) -> Any:
    """``value`` as the executor's tasks best receive it: a Dask cluster gets it once (scattered
    to every worker) and each task a reference; a process pool pickles it with each task."""
    if isinstance(executor, DaskExecutor):
        return executor.client.scatter(value, broadcast=True, hash=False)
    return value


def _module_file(module: str) -> Path | None:
    """The file (a module) or folder (a package) ``module`` is imported from here, when it
    is the user's own code (not part of an installed distribution)."""
    top = module.split(".")[0]
    cwd = str(Path.cwd())
    added = cwd not in sys.path
    if added:  # policies are looked up in the current folder too (skymule.policies)
        sys.path.append(cwd)
    try:
        found = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        found = None
    finally:
        if added:
            sys.path.remove(cwd)
    if found is None or not found.origin or found.origin in ("built-in", "frozen"):
        return None
    origin = Path(found.origin)
    if any(part in ("site-packages", "dist-packages") for part in origin.parts):
        return None  # installed: the workers need the same installation
    return origin.parent if found.submodule_search_locations else origin


def ship_modules(executor: Executor, modules: Sequence[str], scratch: Path) -> list[Path]:
    """Upload the user's policy modules to a remote Dask cluster's workers
    (``client.upload_file``: a module file as is, a package as a zip); returns what was sent.

    Workers of the other executors import them from this machine's files as the sweep
    process does.
    """
    if not isinstance(executor, DaskExecutor) or executor.local:
        return []
    sent = []
    for module in sorted(set(modules)):
        source = _module_file(module)
        if source is None:
            continue
        if source.is_dir():
            archive = scratch / f"{source.name}.zip"
            with zipfile.ZipFile(archive, "w") as bundle:
                for file in sorted(source.rglob("*.py")):
                    bundle.write(file, Path(source.name) / file.relative_to(source))
            source = archive
        # a .py lands in the workers' folder, which is on their path; a zip is put on the
        # path by loading it
        executor.client.upload_file(str(source), load=source.suffix == ".zip")
        sent.append(source)
    return sent


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise SkymuleError("the Dask executors need Dask: pip install 'skymule[dask]'") from None
    return distributed


DASK_START_TIMEOUT_S = 120
"""Seconds a local Dask cluster may take to connect its workers (Dask's default is 30 s)."""


QUIET_DASK: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.scheduler.work-stealing": False,
    "distributed.nanny.pre-spawn-environ": {
        "OMP_NUM_THREADS": 1,
        "MKL_NUM_THREADS": 1,
        "OPENBLAS_NUM_THREADS": 1,
    },
}
"""Dask settings for a local cluster running sweep chunks (and the docs' advice for a remote
one). Dask's defaults cost CPU in proportion to wall time, not work: each worker samples its
task's stack every 10 ms (profiling), every event loop checks its health every 20 ms, and
the nanny sets ``MALLOC_TRIM_THRESHOLD_``, which also fixes glibc's mmap threshold so every
large numpy array is mapped and unmapped again. Chunks are equal and few, so work stealing
only adds its periodic checks."""


def _start_local_cluster(distributed: Any, workers: int) -> Any:
    """A ``LocalCluster`` that opens no well-known port and survives a slow start.

    The scheduler's HTTP server (dashboard, health and metrics routes) binds port 8787 unless
    told otherwise, even with the dashboard off, and warns when 8787 is taken, so the port is
    ``127.0.0.1:0`` (any free one) and the dashboard stays off. On a loaded machine a worker
    can miss Dask's default 30-s connect timeout and the cluster fails with "Cluster closed
    without starting up" (seen in CI, issue 15): the connect timeout is raised to
    ``DASK_START_TIMEOUT_S`` and a failed start is retried once.
    """
    import dask

    options: dict[str, Any] = {
        "n_workers": workers,
        "threads_per_worker": 1,
        "host": "127.0.0.1",
        "dashboard_address": "127.0.0.1:0",
        "scheduler_kwargs": {"dashboard": False},
        "memory_limit": 0,  # no memory monitor: a chunk stays within CHUNK_MEMORY_BYTES
        # the workers' logs are noise in a command line: a task's error reaches the sweep
        # through its future, and on Ctrl-C the workers log the closed scheduler's
        # connection (failed heartbeats, CommClosedError) as errors
        "silence_logs": logging.CRITICAL,
    }
    timeout = f"{DASK_START_TIMEOUT_S}s"
    settings = {"distributed.comm.timeouts.connect": timeout, **QUIET_DASK}
    with dask.config.set(settings), _workers_deaf_to_ctrl_c():
        try:
            return distributed.LocalCluster(**options)
        except (RuntimeError, OSError, TimeoutError):
            return distributed.LocalCluster(**options)  # once more: a busy machine, not a bug


@contextmanager
def _workers_deaf_to_ctrl_c() -> Iterator[None]:
    """Start worker processes (local Dask workers, process-pool workers) ignoring SIGINT, so
    a Ctrl-C in the terminal (sent to the whole process group) stops the sweep process,
    which closes the cluster or pool; otherwise every worker process prints its own
    KeyboardInterrupt traceback. An ignored SIGINT is
    the one setting a spawned process inherits (a handler or a blocked mask is reset at
    exec); the sweep process ignores it too while its workers start (a few seconds)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def _closing_quietly() -> Iterator[None]:
    """Wrap a Dask client and cluster so that Ctrl-C or SIGTERM closes them in silence.

    Closing an interrupted cluster makes Dask, tornado and asyncio log connection errors
    (``CommClosedError``, ``Exception in callback``) with tracebacks, and a second Ctrl-C
    during the close breaks it off half-way, so the workers then log failed heartbeats: the
    command must print one line and the resume command instead. On the interrupt, logging is
    disabled and further SIGINT/SIGTERM are ignored until the close is done (the interrupt
    itself is already on its way up); both are put back when this block ends.
    """
    main = threading.current_thread() is threading.main_thread()
    handlers = {n: signal.getsignal(n) for n in (signal.SIGINT, signal.SIGTERM)} if main else {}
    disabled = logging.root.manager.disable
    try:
        yield
    finally:
        logging.disable(disabled)
        for number, handler in handlers.items():
            signal.signal(number, handler)


@contextmanager
def _quiet_when_interrupted() -> Iterator[None]:
    """The inner half of :func:`_closing_quietly`: on an interrupt, silence and ignore."""
    try:
        yield
    except KeyboardInterrupt:
        logging.disable(logging.CRITICAL)
        if threading.current_thread() is threading.main_thread():
            for number in (signal.SIGINT, signal.SIGTERM):
                signal.signal(number, signal.SIG_IGN)
        raise


@contextmanager
def _dask_local(
    workers: int | None, scheduler: str | None, warm: tuple[str, ...] = ()
) -> Iterator[Executor]:
    distributed = _distributed()
    with _closing_quietly():
        cluster = _start_local_cluster(distributed, workers or default_workers())
        with (
            cluster,
            distributed.Client(cluster, timeout=f"{DASK_START_TIMEOUT_S}s") as client,
            _quiet_when_interrupted(),
        ):
            yield DaskExecutor(client, local=True)


@contextmanager
def _dask(
    workers: int | None, scheduler: str | None, warm: tuple[str, ...] = ()
) -> Iterator[Executor]:
    if not scheduler:
        raise SkymuleError("--executor dask needs --scheduler tcp://HOST:PORT")
    distributed = _distributed()
    try:
        client = distributed.Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise SkymuleError(f"--scheduler {scheduler!r}: cannot connect ({exc})") from None
    with _closing_quietly(), client, _quiet_when_interrupted():
        yield DaskExecutor(client, local=False)


ExecutorFactory = Callable[
    [int | None, str | None, tuple[str, ...]], AbstractContextManager[Executor]
]

EXECUTORS: Registry[ExecutorFactory] = Registry("--executor")
"""Executor registry: name -> context manager (workers, scheduler, modules to import in each
new worker; only the local process pool uses them) yielding an Executor."""

EXECUTORS.register("inprocess", _inprocess)
EXECUTORS.register("process", _process)
EXECUTORS.register("dask-local", _dask_local)
EXECUTORS.register("dask", _dask)


def open_executor(
    name: str,
    workers: int | None = None,
    scheduler: str | None = None,
    warm: tuple[str, ...] = (),
) -> AbstractContextManager[Executor]:
    """The named executor; ``scheduler`` alone selects ``dask``; ``warm``: modules a local
    worker imports as it starts."""
    if scheduler and name in ("process", "dask"):
        name = "dask"
    factory = EXECUTORS.get(name)
    if workers is not None and workers < 1:
        raise SkymuleError(f"--workers {workers}: allowed: an integer >= 1")
    return factory(workers, scheduler, warm)
