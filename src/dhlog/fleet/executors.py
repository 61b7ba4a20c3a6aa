"""Where a batch's jobs run: a pool of worker processes on this machine (``dhlog batch
--executor process``, the default) or a Dask cluster (``--executor dask``: one started here with a
worker process of one thread per ``--jobs``, or the one whose scheduler is at ``--scheduler``).

Both take a function ``work`` (a module's function, or a partial of one: a worker imports it by
name), the items, ``on_done`` called with each row as its item finishes, and ``lost`` (the row of
an item whose worker died or whose task raised), and return the rows in the items' order. They
know nothing of logs: :func:`dhlog.fleet.batch.run_batch` gives them ``process_job``.

Dask rather than Ray: Dask's ``distributed`` is pure-Python wheels on PyPI (Ray's are compiled,
over 100 MB installed, and its runtime heavier for a 2-core machine), ``LocalCluster`` gives a
test a real cluster in its own process, its futures are those of ``concurrent.futures``, and a
scheduler runs wherever Python does. What the engine gives (placement, retries of a lost
worker, a dashboard) and what dhlog gives: ``docs/performance.md``, "Beyond one machine: Dask".
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from dhlog.errors import DhlogError

Row = dict[str, Any]
Item = TypeVar("Item")

#: The engines a batch runs on.
EXECUTORS = ("process", "dask")


class ExecutorError(DhlogError):
    """The engine a batch was asked to run on cannot be used; nothing was processed."""


class DaskMissingError(ExecutorError):
    def __init__(self) -> None:
        super().__init__(
            "--executor dask needs Dask's distributed package, which is not installed: "
            "pip install 'dhlog[dask]'."
        )


class SchedulerUnreachableError(ExecutorError):
    def __init__(self, address: str, why: str) -> None:
        self.address = address
        super().__init__(
            f"cannot reach a Dask scheduler at {address} ({why}); check that the scheduler "
            "runs there and the address and port it printed, or leave out --scheduler to start "
            "a cluster on this machine. Nothing was written."
        )


# ----------------------------------------------------------------------------- process pool

#: Seconds a worker has to end after SIGTERM before it is killed.
STOP_GRACE = 2.0
#: Seconds between the pool's checks for a signal: Python acts on a signal in its main thread
#: only, and a signal the kernel gave another thread does not wake a main thread that waits.
WAKE_EVERY = 0.2


def run_in_processes(
    work: Callable[[Item], Row],
    items: Sequence[Item],
    workers: int,
    *,
    lost: Callable[[Item, str], Row],
    on_done: Callable[[Row], None] | None = None,
) -> list[Row]:
    """``work`` on every item in a pool of ``workers`` spawned processes.

    The workers never see the terminal's Ctrl-C (SIGINT is held while they are started, so they
    begin with it held, and they ignore it). An exception here (an interrupt above all) sends
    them SIGTERM, on which a worker busy with an item raises where it is (its temporary files
    removed on the way out) and exits, killed when it has not within ``STOP_GRACE`` seconds: no
    worker outlives the call."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    rows: list[Row | None] = [None] * len(items)
    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_start)
    try:
        with sigint_held():  # the workers start with SIGINT held (a mask is inherited)
            futures = {pool.submit(_worker_item, work, item): k for k, item in enumerate(items)}
        pending = set(futures)
        while pending:  # short waits: a signal another thread took is acted on within one
            finished, pending = wait(pending, timeout=WAKE_EVERY, return_when=FIRST_COMPLETED)
            for future in sorted(finished, key=futures.__getitem__):
                k = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # a worker that died (out of memory, killed)
                    row = lost(items[k], f"the worker stopped ({exc}).")
                rows[k] = row
                if on_done is not None:
                    on_done(row)
    except BaseException:
        _stop_workers(pool)
        raise
    pool.shutdown()
    return [r for r in rows if r is not None]


@contextmanager
def sigint_held() -> Iterator[None]:
    """SIGINT held (blocked, not lost: delivered after the block) in this thread: processes
    and threads started in the block begin with it held, so the terminal's Ctrl-C, sent to
    every process of the foreground group, never reaches a worker (a worker importing its
    modules would print a traceback).

    The kernel may still give a Ctrl-C to another thread of this process (one that does not
    block it), and Python then runs the handler in the main thread at its next step — which,
    in the block, may be between a worker's start and the writing of its set-up to it (the
    worker then reads an empty pipe and prints a traceback). So, in the main thread, a SIGINT
    in the block is only noted, and acted on as the handler before it would when the block
    ends."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    noted: list[int] = []
    main = threading.current_thread() is threading.main_thread()
    handler = signal.signal(signal.SIGINT, lambda s, f: noted.append(s)) if main else None

    def restore() -> None:
        # the mask first (a SIGINT held meanwhile is then only noted), then the handler (one
        # set outside Python reads as None: the default then)
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
        if main:
            signal.signal(signal.SIGINT, signal.SIG_DFL if handler is None else handler)

    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    except BaseException as exc:
        restore()
        if noted and not isinstance(exc, KeyboardInterrupt):
            raise KeyboardInterrupt from exc  # the Ctrl-C is not lost to the failure
        raise
    restore()
    if noted:
        if callable(handler):
            handler(signal.SIGINT, None)
        elif handler != signal.SIG_IGN:
            raise KeyboardInterrupt


class _WorkerStopped(BaseException):
    """SIGTERM in a worker busy with an item: raised where it is, so the item's temporary
    files are removed on the way out."""


_BUSY = False


def _on_worker_sigterm(signum: int, frame: object) -> None:
    if _BUSY:
        raise _WorkerStopped()
    os._exit(128 + signum)  # idle: nothing to clean up, nothing to say


def _worker_start() -> None:
    """A worker's set-up: SIGINT ignored (the parent stops the workers), SIGTERM ends it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_worker_sigterm)


def _worker_item(work: Callable[[Item], Row], item: Item) -> Row:
    """``work(item)`` in a worker: on SIGTERM the worker leaves no temporary file and ends
    without a word (``os._exit``: no traceback, no finaliser of a half-built recording)."""
    global _BUSY
    _BUSY = True
    try:
        return work(item)
    except _WorkerStopped:
        os._exit(128 + signal.SIGTERM)
    finally:
        _BUSY = False


def _stop_workers(pool: Any) -> None:
    """Cancel what has not started, end every worker (SIGTERM, then SIGKILL after
    ``STOP_GRACE`` seconds), then wait (``STOP_GRACE`` seconds at most) for the pool's manager
    thread to end.

    That thread, seeing its workers gone, closes the pipe that wakes it, and the exit hook of
    ``concurrent.futures`` (``_python_exit``) writes to that pipe without the lock the closing
    takes (CPython 3.11; python/cpython gh-125451 gave the pipe its own lock in 3.12.8 and
    3.13.1): an exit while the thread is closing it prints ``OSError: [Errno 9] Bad file
    descriptor`` with a traceback. Once the thread has ended, the pipe is marked closed and the
    hook leaves it alone."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)  # shutdown() forgets it
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    deadline = time.monotonic() + STOP_GRACE
    for p in processes:
        p.join(max(0.0, deadline - time.monotonic()))
    for p in processes:
        if p.is_alive():
            p.kill()
            p.join(1.0)
    if manager is not None:
        manager.join(STOP_GRACE)


# ------------------------------------------------------------------------------------- Dask

#: Seconds to reach the scheduler at ``--scheduler`` before giving up.
CONNECT_TIMEOUT = 10.0
#: Seconds the client, and a cluster started here, have to close.
CLOSE_TIMEOUT = 10.0


def run_on_dask(
    work: Callable[[Item], Row],
    items: Sequence[Item],
    workers: int,
    *,
    scheduler: str | None = None,
    lost: Callable[[Item, str], Row],
    on_done: Callable[[Row], None] | None = None,
) -> list[Row]:
    """``work`` on every item as a task of a Dask cluster: the one whose scheduler is at
    ``scheduler`` (``tcp://host:8786``, reached within ``CONNECT_TIMEOUT`` seconds or
    :class:`SchedulerUnreachableError`), or one started here for the call with ``workers``
    processes of one thread each (begun with SIGINT held, as the pool's). Workers elsewhere get
    the items as they are: paths in them must name the same files there.

    A task whose workers died (Dask tries it on others first: ``distributed.scheduler.
    allowed-failures``, 3) or that raised is ``lost(item, reason)``. An exception here (an
    interrupt above all) cancels the tasks not started and stops the running ones (an exception
    raised in each one's thread, as SIGTERM does in a pool's worker: its temporary files
    removed, never while it moves its results into place), then closes the client and a cluster
    started here."""
    distributed = _distributed()
    cluster: Any = None
    if scheduler is None:
        cluster = _local_cluster(distributed, workers)
    try:
        client = _connect(distributed, scheduler or cluster.scheduler_address)
        try:
            return _run_tasks(distributed, client, work, items, lost, on_done)
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=CLOSE_TIMEOUT)
    finally:
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=CLOSE_TIMEOUT)


def _local_cluster(distributed: Any, workers: int) -> Any:
    """A Dask cluster on this machine: ``workers`` processes of one thread each."""
    from multiprocessing import resource_tracker

    # started now: started by the cluster's thread (with its first worker), it would unblock
    # SIGINT there (its start blocks SIGINT and SIGTERM, and then unblocks both)
    resource_tracker.ensure_running()
    cluster = None
    try:
        with sigint_held():  # its threads too: the workers are started from one of them
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                # its HTTP server (health, metrics) on a free port: on 8787 taken by another
                # cluster, it would warn
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                silence_logs=logging.ERROR,
            )
    except Exception as exc:
        raise ExecutorError(
            f"cannot start a Dask cluster of {workers} worker(s) on this machine ({exc}); "
            "try --executor process. Nothing was written."
        ) from None
    except BaseException:  # a Ctrl-C held while it started: it is closed again
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=CLOSE_TIMEOUT)
        raise
    return cluster


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise DaskMissingError() from None
    return distributed


def _connect(distributed: Any, address: str) -> Any:
    """A client of the scheduler at ``address``, or :class:`SchedulerUnreachableError`."""
    try:
        client = distributed.Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except ValueError as exc:  # a malformed address
        why = str(exc)
    except OSError:  # refused, or no answer: Dask tries again until the timeout
        why = f"no answer within {CONNECT_TIMEOUT:g} s"
    except Exception as exc:  # something else answered there
        why = f"what answers there is not a Dask scheduler: {type(exc).__name__}"
    else:
        return client
    # raised here, outside the handlers: the half-made client (held by the traceback) is
    # closed now, while its event loop runs, not at exit with a traceback of its own
    raise SchedulerUnreachableError(address, why)


def _run_tasks(
    distributed: Any,
    client: Any,
    work: Callable[[Item], Row],
    items: Sequence[Item],
    lost: Callable[[Item, str], Row],
    on_done: Callable[[Row], None] | None,
) -> list[Row]:
    batch = uuid.uuid4().hex
    keys = [f"dhlog-batch-{k}-{batch}" for k in range(len(items))]
    futures: dict[Any, int] = {}
    rows: list[Row | None] = [None] * len(items)
    try:
        submitted = client.map(_dask_task, items, work=work, batch=batch, key=keys, pure=False)
        futures = {future: k for k, future in enumerate(submitted)}
        for future in distributed.as_completed(submitted, loop=client.loop):  # wakes each 0.1 s
            k = futures[future]
            try:
                row = future.result()
            except distributed.KilledWorker as exc:  # its workers died, each in turn
                row = lost(items[k], f"the worker stopped ({exc}).")
            except distributed.CancelledError as exc:  # the scheduler lost, or was lost
                row = lost(items[k], f"the cluster dropped the task ({exc}).")
            except Exception as exc:  # raised on the worker (dhlog missing there, say)
                row = lost(
                    items[k], f"the task raised on its worker ({type(exc).__name__}: {exc})."
                )
            rows[k] = row
            if on_done is not None:
                on_done(row)
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(list(futures), force=True)  # those not started never will
        with contextlib.suppress(Exception):
            client.run(_stop_batch, batch, on_error="ignore")  # those running end now
        raise
    return [r for r in rows if r is not None]


class _TaskStopped(BaseException):
    """Raised in a Dask worker's thread running a task of a stopped batch (:func:`_stop_batch`)."""


#: In a Dask worker: the threads running each batch's tasks, and the batches stopped.
_RUNNING: dict[str, set[int]] = {}
_STOPPED: set[str] = set()
_TASKS_LOCK = threading.Lock()


def _dask_task(item: Item, *, work: Callable[[Item], Row], batch: str) -> Row | None:
    """``work(item)`` in a Dask worker's thread, which :func:`_stop_batch` may stop (None then:
    the batch that asked for the row is gone)."""
    from dhlog.io.writer import forget_stop

    ident = threading.get_ident()
    try:
        try:
            with _TASKS_LOCK:
                if batch in _STOPPED:
                    return None
                _RUNNING.setdefault(batch, set()).add(ident)
            return work(item)
        finally:
            with _TASKS_LOCK:
                running = _RUNNING.get(batch, set())
                running.discard(ident)
                if not running:
                    _RUNNING.pop(batch, None)
                forget_stop()  # a stop asked as the task ended: not for the thread's next task
    except _TaskStopped:
        return None


def _stop_batch(batch: str) -> int:
    """In a Dask worker (``Client.run``): the batch's tasks not started return at once, the
    running ones are stopped (:func:`dhlog.io.writer.stop_thread`); how many were running."""
    from dhlog.io.writer import stop_thread

    with _TASKS_LOCK:
        _STOPPED.add(batch)
        threads = _RUNNING.pop(batch, set())
        for ident in threads:
            stop_thread(ident, _TaskStopped)
    return len(threads)
