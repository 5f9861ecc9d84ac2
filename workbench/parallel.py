"""Independent work on several cores, with results identical to one process.

* A :class:`Task` is a picklable call ``Task(func, *args, **kwargs)``. Its result must depend
  on its arguments only (every random component seeded), so where it runs does not matter.
* A *plan* is a generator that yields lists of tasks and receives their results (a list in
  the same order; a task's exception is raised at the ``yield``); what it returns is the
  plan's result. E.g. :class:`~workbench.BaseBoostCV` yields its folds, decides, then yields
  its refit.
* :func:`run_plans` runs many plans at once: their tasks go to worker processes as workers
  become free, a plan's later stages first (a target's refit starts as soon as its folds
  end, while other targets' folds still run), then higher ``Task.priority``, then earlier
  plans and positions. With
  ``n_jobs=1`` (or inside a worker) every task runs in this process, in order.
* :func:`map_tasks`: the results of independent tasks, in order.
* :func:`start`: one task started now on a worker of the enclosing :func:`worker_pool`, its
  result collected later (:meth:`Started.result`), while this process goes on with other
  work (its own plans share the workers): independent phases of one command side by side.
  Without a pool it runs at :meth:`Started.result`, in this process.
* :func:`worker_pool`: ``with worker_pool(n_jobs):`` keeps one set of workers for every call
  inside the block (a command's fit, learning curves and figures); without it, each parallel
  call starts its workers and ends them.

Workers are forked from this process when first needed (a command forks them as it starts,
``worker_pool(..., eager=True)``, before it starts any thread), so they inherit its imported
modules and data (no re-import); each runs one BLAS/OpenMP thread (threadpoolctl, and
``OMP_NUM_THREADS=1`` etc. for libraries loaded later), runs its tasks' fits serially,
ignores SIGINT (the parent handles it and ends them) and dies with its parent. They are
the one worker mechanism: a sweep's ``--workers`` are tasks on them too. Where ``fork`` is
unavailable (Windows; macOS by default) joblib's processes run the tasks. Warnings raised
in a task are issued again in the parent, where its filters apply. The core estimators'
``n_jobs`` follows scikit-learn: ``None`` is 1, ``-1`` every core.
"""

from __future__ import annotations

import contextlib
import heapq
import multiprocessing
import os
import signal
import sys
import time
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = ["Started", "Task", "die_with_parent", "effective_n_jobs", "gather", "in_worker",
           "init_worker", "map_tasks", "pid_alive", "prioritised", "run_plans", "start",
           "start_workers", "worker_pool"]

THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
              "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")

#: Seconds ended workers have to exit after SIGTERM before they are killed.
KILL_GRACE_S = 5.0

_IN_WORKER = False
_AMBIENT: list[_Pool] = []  # the pools of the enclosing ``worker_pool`` blocks
_WARNING_REGISTRY: dict = {}  # "default"-action bookkeeping of re-issued warnings


class Task:
    """A picklable call: ``Task(func, *args, **kwargs)()`` is ``func(*args, **kwargs)``.
    ``priority`` (default 0): on several processes, among ready tasks of the same stage,
    higher goes first (e.g. the expected cost, so long tasks do not come last).

    Parameters
    ----------
    func : callable
        The function (picklable: a module's, not a lambda).
    *args, **kwargs
        Its arguments.
    """

    __slots__ = ("func", "args", "kwargs", "priority")

    def __init__(self, func: Callable, *args: Any, **kwargs: Any) -> None:
        self.func, self.args, self.kwargs = func, args, kwargs
        self.priority = 0

    def __call__(self) -> Any:
        """Run the task: ``func(*args, **kwargs)``."""
        return self.func(*self.args, **self.kwargs)

    def __repr__(self) -> str:
        """Name the task's function."""
        return f"Task({getattr(self.func, '__qualname__', self.func)!r})"


Plan = Generator[list, list, Any]


def effective_n_jobs(n_jobs: int | None) -> int:
    """Processes for ``n_jobs`` (``None``: 1; ``-1``: every core this process may use;
    ``-k``: all but ``k - 1``); 1 inside a worker.

    Parameters
    ----------
    n_jobs : int or None
        The processes asked for.

    Returns
    -------
    int
        The processes to use, 1 or more.

    Raises
    ------
    ValueError
        For 0.
    """
    if _IN_WORKER or n_jobs is None:
        return 1
    n_jobs = int(n_jobs)
    if n_jobs == 0:
        raise ValueError("n_jobs == 0: give a number of processes >= 1, or -1 for every core")
    if n_jobs < 0:
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            cores = os.cpu_count() or 1
        n_jobs = max(1, cores + 1 + n_jobs)
    return n_jobs


def in_worker() -> bool:
    """Whether this process is one of :func:`run_plans`'s workers.

    Returns
    -------
    bool
        True in a worker.
    """
    return _IN_WORKER


# --------------------------------------------------------------------------- workers


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (on this host; another user's counts).

    Parameters
    ----------
    pid : int
        The process id.

    Returns
    -------
    bool
        Whether it exists.
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def die_with_parent(parent: int, sig: int = signal.SIGKILL) -> None:
    """End this process with ``sig`` when its parent ``parent`` ends (Linux's
    ``PR_SET_PDEATHSIG``), and exit now if ``parent`` is gone already.

    Parameters
    ----------
    parent : int
        The parent's process id.
    sig : int, default=signal.SIGKILL
        The signal.
    """
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, sig)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if not pid_alive(parent):  # the parent died before prctl
        os._exit(128 + sig)


_ENDING_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def _signals_blocked() -> Iterator[None]:
    """Block SIGINT and SIGTERM in this thread while the block runs (a process forked in it
    starts with them blocked); one that arrives meanwhile is delivered after it."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _ENDING_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def init_worker(parent: int) -> None:
    """Make this process a worker of process ``parent``: :func:`effective_n_jobs` is 1 here
    (the parent spreads the work; no nested processes), one BLAS/OpenMP thread, SIGINT
    ignored (the parent handles it and ends its workers; a task may handle signals itself,
    as a sweep's worker does to queue its running trial again), SIGTERM's default action,
    and killed with its parent (:func:`die_with_parent`). The pool forks with SIGINT and
    SIGTERM blocked: they are unblocked here, once these dispositions replace the
    parent's handlers.

    Parameters
    ----------
    parent : int
        The parent's process id.
    """
    global _IN_WORKER
    _IN_WORKER = True
    _AMBIENT.clear()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _ENDING_SIGNALS)  # blocked across the fork
    die_with_parent(parent, signal.SIGKILL)
    os.environ.update({k: "1" for k in THREAD_ENV})
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except Exception:  # threadpoolctl missing or a library it cannot drive
        pass


def _call(task: Task) -> tuple[Any, list[tuple[str, type[Warning], str, int]]]:
    """Run a task in a worker: its result, and the warnings it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = task()
    return result, [(str(w.message), w.category, w.filename, w.lineno) for w in caught]


_MODULES: dict[str, str] = {}


def _module_of(filename: str) -> str | None:
    """The name of the loaded module whose file is ``filename`` (warning filters match it)."""
    if filename not in _MODULES:
        for name, mod in list(sys.modules.items()):
            path = getattr(mod, "__file__", None)
            if path:
                _MODULES.setdefault(path, name)
    return _MODULES.get(filename)


def _reissue(caught: Iterable[tuple[str, type[Warning], str, int]]) -> None:
    for message, category, filename, lineno in caught:
        module = _module_of(filename) or os.path.splitext(os.path.basename(filename))[0]
        warnings.warn_explicit(message, category, filename, lineno, module=module,
                               registry=_WARNING_REGISTRY)


class _Pool:
    """Forked worker processes (created on first use)."""

    def __init__(self, n_jobs: int) -> None:
        self.n_jobs = n_jobs
        self._executor: ProcessPoolExecutor | None = None

    @property
    def executor(self) -> ProcessPoolExecutor:
        if self._executor is None:
            ctx = multiprocessing.get_context("fork")
            ex = ProcessPoolExecutor(self.n_jobs, mp_context=ctx, initializer=init_worker,
                                     initargs=(os.getpid(),))
            # ProcessPoolExecutor forks every worker in its first submit. A child starts
            # with this process's Python signal handlers: a SIGTERM (the pool ended at once,
            # e.g. a config error) landing just after fork() ran the command's handler there
            # and unwound the child into this process's stack, a second copy of the command
            # (and of a pytest worker). Blocked across the fork, in the child a signal waits
            # for init_worker's own dispositions.
            with _signals_blocked():
                ex.submit(int)
            self._executor = ex
        return self._executor

    def close(self, *, kill: bool = False) -> None:
        ex, self._executor = self._executor, None
        if ex is None:
            return
        if kill:  # interrupted or failed: do not wait for running tasks
            procs = list((getattr(ex, "_processes", None) or {}).values())
            ex.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                with contextlib.suppress(Exception):
                    p.terminate()
            # SIGTERM lets a task that handles it end cleanly (a sweep's worker queues its
            # trial); one that outlives the grace is killed: a live worker would hold the
            # interpreter's exit, which joins the pool's processes
            deadline = time.monotonic() + KILL_GRACE_S
            for p in procs:
                with contextlib.suppress(Exception):
                    p.join(timeout=max(0.0, deadline - time.monotonic()))
            for p in procs:
                with contextlib.suppress(Exception):
                    if p.is_alive():
                        p.kill()
                        p.join(timeout=1)
        else:
            ex.shutdown(wait=True)


def _fork_available() -> bool:
    return "fork" in multiprocessing.get_all_start_methods() and sys.platform != "darwin"


@contextlib.contextmanager
def worker_pool(n_jobs: int | None, *, eager: bool = False) -> Iterator[int]:
    """Keep ``n_jobs`` workers for every parallel call inside the block (forked on first
    use, or at once with ``eager``: a command enters it before it starts any thread, so
    that no process is forked while another thread holds a lock). With one process (or
    inside a worker) it does nothing.

    Parameters
    ----------
    n_jobs : int or None
        Processes: ``None`` 1, ``-1`` every core, ``-k`` all but ``k - 1``.
    eager : bool, default=False
        Fork the workers on entering the block.

    Yields
    ------
    int
        The number of processes.
    """
    jobs = effective_n_jobs(n_jobs)
    if jobs <= 1 or not _fork_available():
        yield jobs
        return
    pool = _Pool(jobs)
    _AMBIENT.append(pool)
    ok = False
    try:
        if eager:
            start_workers(jobs)
        yield jobs
        ok = True
    finally:
        _AMBIENT.remove(pool)
        pool.close(kill=not ok)


def start_workers(n_jobs: int | None) -> None:
    """Fork the enclosing :func:`worker_pool`'s processes now, from this thread (no-op
    without a pool or when they run already): call it before starting a thread that will
    run plans, so that no process is forked while another thread of this one holds a lock.

    Parameters
    ----------
    n_jobs : int or None
        Processes: ``None`` 1, ``-1`` every core, ``-k`` all but ``k - 1``.
    """
    if not _AMBIENT or effective_n_jobs(n_jobs) <= 1 or not _fork_available():
        return
    pool = _AMBIENT[-1]
    if pool._executor is None:
        pool.executor.submit(int).result()  # forked: one has started


# --------------------------------------------------------------------------- plans


def _advance(plan: Plan, results: Any = None,
             error: BaseException | None = None) -> list:
    """Send results (or throw an error) into a plan: its next batch, or ``StopIteration``."""
    if error is not None:
        return plan.throw(error)
    return plan.send(results)


def _check_batch(batch: Iterable[Task]) -> list[Task]:
    batch = list(batch)
    if not batch or not all(isinstance(t, Task) for t in batch):
        raise TypeError(f"a plan must yield a non-empty list of Task objects, got {batch!r}")
    return batch


def _first_batches(plans: list[Plan]) -> tuple[list, dict[int, list[Task]]]:
    """Start every plan: ``out`` (the results of plans that ended at once) and the first
    batch of each other plan, by position."""
    out: list[Any] = [None] * len(plans)
    batches: dict[int, list[Task]] = {}
    for i, plan in enumerate(plans):
        try:
            batches[i] = _check_batch(next(plan))
        except StopIteration as stop:
            out[i] = stop.value
    return out, batches


def _run_serial(plan: Plan) -> Any:
    try:
        batch = _check_batch(next(plan))
        while True:
            try:
                results = [task() for task in batch]
            except Exception as exc:
                batch = _check_batch(_advance(plan, error=exc))
            else:
                batch = _check_batch(_advance(plan, results))
    except StopIteration as stop:
        return stop.value


def _run_joblib(plans: list[Plan], jobs: int) -> list:
    """Plans in rounds through joblib's processes (where fork is unavailable)."""
    from joblib import Parallel, delayed

    out, batches = _first_batches(plans)
    with Parallel(n_jobs=jobs) as parallel:
        while batches:
            flat = [(i, t) for i, batch in batches.items() for t in batch]
            results = parallel(delayed(_call)(t) for _, t in flat)
            grouped: dict[int, list] = {i: [] for i in batches}
            for (i, _), (value, caught) in zip(flat, results):
                _reissue(caught)
                grouped[i].append(value)
            for i, values in grouped.items():
                try:
                    batches[i] = _check_batch(_advance(plans[i], values))
                except StopIteration as stop:
                    out[i] = stop.value
                    del batches[i]
    return out


def run_plans(plans: Iterable[Plan], n_jobs: int | None = None) -> list:
    """Run plans (see the module doc) on ``n_jobs`` processes; the result is the same for
    every ``n_jobs``.

    Parameters
    ----------
    plans : iterable of Plan
        The plans.
    n_jobs : int, default=None
        Processes (``None``: 1; ``-1``: every core).

    Returns
    -------
    list
        Each plan's value, in order.
    """
    plans = list(plans)
    jobs = effective_n_jobs(n_jobs)
    if jobs <= 1 or not plans:
        return [_run_serial(p) for p in plans]
    if not _fork_available():
        return _run_joblib(plans, jobs)
    ambient = _AMBIENT[-1] if _AMBIENT else None
    pool = ambient if ambient is not None else _Pool(jobs)
    jobs = min(jobs, pool.n_jobs)
    ok = False
    try:
        out = _drive(plans, pool.executor, jobs)
        ok = True
        return out
    except BrokenProcessPool as exc:
        raise RuntimeError(f"a worker process died ({exc}); was it killed or out of "
                           "memory?") from None
    finally:
        if ambient is None:
            pool.close(kill=not ok)
        elif not ok:  # interrupted mid-way: do not leave tasks running for the next call
            pool.close(kill=True)


def _drive(plans: list[Plan], executor: ProcessPoolExecutor, jobs: int) -> list:
    out: list[Any] = [None] * len(plans)
    stage = [0] * len(plans)
    results: dict[int, list] = {}
    missing: dict[int, int] = {}
    errors: dict[int, BaseException] = {}
    ready: list[tuple] = []  # (-stage, -priority, plan, position, task)

    def push(i: int, batch: Iterable[Task]) -> None:
        batch = _check_batch(batch)
        results[i] = [None] * len(batch)
        missing[i] = len(batch)
        for k, task in enumerate(batch):
            heapq.heappush(ready, (-stage[i], -task.priority, i, k, task))

    def step(i: int, values: list | None = None, error: BaseException | None = None,
             first: bool = False) -> None:
        try:
            batch = next(plans[i]) if first else _advance(plans[i], values, error)
        except StopIteration as stop:
            out[i] = stop.value
            return
        stage[i] += 0 if first else 1
        push(i, batch)

    for i in range(len(plans)):
        step(i, first=True)
    running: dict[Any, tuple[int, int]] = {}
    while ready or running:
        while ready and len(running) < jobs:
            *_, i, k, task = heapq.heappop(ready)
            running[executor.submit(_call, task)] = (i, k)
        done, _ = wait(running, return_when=FIRST_COMPLETED)
        for future in sorted(done, key=lambda f: running[f]):
            i, k = running.pop(future)
            try:
                value, caught = future.result()
            except BrokenProcessPool:
                raise
            except Exception as exc:
                errors.setdefault(i, exc)
            else:
                _reissue(caught)
                results[i][k] = value
            missing[i] -= 1
            if missing[i] == 0:
                step(i, results.pop(i), errors.pop(i, None))
    return out


def prioritised(plan: Plan, offset: float) -> Plan:
    """``plan`` with ``offset`` added to the priority of each of its tasks (higher runs
    first), e.g. to finish one group of plans before the next starts.

    Parameters
    ----------
    plan : Plan
        The plan.
    offset : float
        Added to each task's priority.

    Returns
    -------
    object
        ``plan``'s value.

    Yields
    ------
    list of Task
        Each batch of ``plan``'s tasks, their priorities raised by ``offset``.
        The batch's results are sent back, in its order.
    """
    try:
        batch = next(plan)
        while True:
            for task in batch:
                task.priority += offset
            try:
                results = yield batch
            except Exception as exc:  # a task's error, thrown into the plan
                batch = plan.throw(exc)
            else:
                batch = plan.send(results)
    except StopIteration as stop:
        return stop.value


def gather(plans: Iterable[Plan]) -> Plan:
    """One plan running several plans side by side (their batches yielded together).

    Parameters
    ----------
    plans : iterable of Plan
        The plans.

    Returns
    -------
    list
        The plans' values, in order.

    Yields
    ------
    list of Task
        The current batches of every plan not yet done, as one batch.
        The batch's results are sent back, in its order.
    """
    plans = list(plans)
    out, batches = _first_batches(plans)
    while batches:
        order = list(batches)
        flat = [t for i in order for t in batches[i]]
        values: list = []
        error: Exception | None = None
        try:
            values = yield flat
        except Exception as exc:  # which task failed is not known here: fail every plan
            error = exc
        pos = 0
        for i in order:
            n = len(batches[i])
            try:
                batches[i] = _check_batch(
                    _advance(plans[i], None if error else values[pos:pos + n], error))
            except StopIteration as stop:
                out[i] = stop.value
                del batches[i]
            pos += n
    return out


def _tasks_plan(tasks: list[Task]) -> Plan:
    return (yield tasks)


class Started:
    """A task under way (:func:`start`): :meth:`result` waits for it and returns its value.

    Parameters
    ----------
    task : Task
        The task.
    future : concurrent.futures.Future, default=None
        Its run on a worker (``None``: it runs at :meth:`result`, here).
    pool : default=None
        The pool it runs on (ended on an interrupt).
    """

    def __init__(self, task: Task, future: Any = None, pool: _Pool | None = None) -> None:
        self._task, self._future, self._pool = task, future, pool

    def result(self) -> Any:
        """The task's value (its exception raised here; its warnings issued here).

        Returns
        -------
        object
            What the task returned.
        """
        if self._future is None:  # no pool: run it now, in this process
            return self._task()
        try:
            value, caught = self._future.result()
        except BrokenProcessPool as exc:
            raise RuntimeError(f"a worker process died ({exc}); was it killed or out of "
                               "memory?") from None
        except BaseException:
            if self._pool is not None and not self._future.done():  # interrupted: end it
                self._pool.close(kill=True)
            raise
        _reissue(caught)
        return value


def start(task: Task, n_jobs: int | None = -1) -> Started:
    """Start ``task`` now on a worker of the enclosing :func:`worker_pool` and return at once.

    The worker runs it serially (one process: inside a worker ``n_jobs`` is 1), beside the
    tasks of this process's plans, which share the other workers (and this one when it is
    done). Its value does not depend on where it runs. Without a pool of several processes
    (``n_jobs`` 1, inside a worker, no ``fork``), it runs when :meth:`Started.result` is
    called, in this process.

    Parameters
    ----------
    task : Task
        The call (picklable, its value a function of its arguments).
    n_jobs : int, default=-1
        Processes allowed (1: run it here, at :meth:`Started.result`).

    Returns
    -------
    Started
        Its :meth:`~Started.result` waits for it.
    """
    if not _AMBIENT or effective_n_jobs(n_jobs) <= 1 or not _fork_available():
        return Started(task)
    pool = _AMBIENT[-1]
    return Started(task, pool.executor.submit(_call, task), pool)


def map_tasks(tasks: Iterable[Task], n_jobs: int | None = None) -> list:
    """The results of independent tasks, in order, computed on ``n_jobs`` processes.

    Parameters
    ----------
    tasks : iterable of Task
        The tasks.
    n_jobs : int, default=None
        Processes (``None``: 1; ``-1``: every core).

    Returns
    -------
    list
        Each task's value, in order.
    """
    tasks = list(tasks)
    if not tasks:
        return []
    return run_plans([_tasks_plan(tasks)], n_jobs)[0]
