"""Local worker processes that run one item at a time and outlive each other's crashes.

``concurrent.futures.ProcessPoolExecutor`` fails every pending item when one worker
dies (``BrokenProcessPool``), without saying which item killed it. :class:`WorkerPool`
gives each worker its own pipe and knows which item each one holds: when a worker
dies (a segfault in a native library, the OOM killer, ``kill -9``), only that item
fails, with its name, stage and the exit signal, and a fresh worker takes the next
item.

Workers are started with the ``spawn`` method (SAPIEN and torch do not survive
``fork`` reliably). ``fn(item, report)`` runs in the worker; ``report(stage)`` sends a
progress note to the driver. ``fn`` must be a module-level function and items and
results must pickle.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import signal
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any, Generic, TypeVar

log = logging.getLogger(__name__)

T = TypeVar("T")


@dataclass
class WorkerDied:
    """What the driver knows of an item whose worker process died."""

    item: Any
    exitcode: int | None
    stage: str | None

    @property
    def reason(self) -> str:
        if self.exitcode is not None and self.exitcode < 0:
            try:
                how = f"signal {signal.Signals(-self.exitcode).name}"
            except ValueError:
                how = f"signal {-self.exitcode}"
        else:
            how = f"exit code {self.exitcode}"
        where = f" in stage {self.stage}" if self.stage else ""
        return f"the worker process died ({how}){where}"


def _worker_main(conn: Connection, fn: Callable[[Any, Callable[[str], None]], Any]) -> None:
    """Loop of one worker: receive an item, run ``fn``, send its result."""
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        index, item = msg

        def report(stage: str, index: int = index) -> None:
            conn.send(("stage", index, stage))

        result = fn(item, report)
        conn.send(("done", index, result))


class _Worker:
    def __init__(self, ctx: Any, fn: Callable) -> None:
        self.conn, child = ctx.Pipe(duplex=True)
        self.process = ctx.Process(target=_worker_main, args=(child, fn), daemon=True)
        self.process.start()
        child.close()
        self.index: int | None = None  # the item it holds
        self.stage: str | None = None

    def give(self, index: int, item: Any) -> None:
        self.index, self.stage = index, None
        self.conn.send((index, item))

    def stop(self) -> None:
        try:
            self.conn.send(None)
        except OSError:
            pass
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


class WorkerPool(Generic[T]):
    """Run ``fn`` over items in ``workers`` processes; see the module docstring."""

    def __init__(self, fn: Callable[[T, Callable[[str], None]], Any], workers: int) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.fn = fn
        self.workers = workers
        self.ctx = mp.get_context("spawn")

    def run(
        self, items: Sequence[T], on_stage: Callable[[T, str], None] | None = None
    ) -> Iterator[tuple[T, Any]]:
        """Yield ``(item, result)`` as items finish, ``result`` a :class:`WorkerDied`
        for an item whose worker died. Every item is yielded exactly once."""
        pending = list(enumerate(items))[::-1]
        pool: list[_Worker] = []
        try:
            while pending or any(w.index is not None for w in pool):
                pool = [w for w in pool if w.index is not None or w.process.is_alive()]
                idle = [w for w in pool if w.index is None]
                while len(pool) < self.workers and len(idle) < len(pending):
                    w = _Worker(self.ctx, self.fn)
                    pool.append(w)
                    idle.append(w)
                for w in idle:
                    if pending:
                        w.give(*pending.pop())
                busy = [w for w in pool if w.index is not None]
                ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy], 1.0)
                for w in busy:
                    if w.conn in ready:
                        try:
                            kind, index, payload = w.conn.recv()
                        except Exception:  # noqa: BLE001 - closed or torn pipe: the worker died
                            pass
                        else:
                            if kind == "stage":
                                w.stage = payload
                                if on_stage is not None:
                                    on_stage(items[index], payload)
                            else:
                                w.index = None
                                yield items[index], payload
                            continue
                    elif w.process.sentinel not in ready:
                        continue
                    w.process.join(timeout=10)
                    index = w.index
                    assert index is not None
                    log.warning("worker %s died holding item %d", w.process.pid, index)
                    died = WorkerDied(items[index], w.process.exitcode, w.stage)
                    w.index = None
                    w.stop()
                    pool.remove(w)
                    yield items[index], died
        finally:
            for w in pool:
                w.stop()
