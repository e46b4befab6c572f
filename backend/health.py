"""Liveness and readiness.

Liveness: the process answers. Readiness: it can do its work, i.e. the database answers a
query (and Redis a ping when `redis_url` is set) within `health_timeout_s`. A backend whose
database refuses connections, or that points at a wrong port, is alive but not ready.
"""

from __future__ import annotations

import asyncio
import weakref
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

from sqlalchemy import Engine, text


@dataclass
class Readiness:
    ready: bool
    checks: dict[str, str] = field(default_factory=dict)  # name -> "ok" or the reason

    @property
    def reason(self) -> str:
        return "; ".join(
            f"{name}: {result}" for name, result in self.checks.items() if result != "ok"
        )


def _ping_database(engine: Engine) -> None:
    with engine.connect() as connection:
        connection.execute(text("SELECT 1"))


def _first_line(error: BaseException) -> str:
    text_ = str(error).strip().splitlines()
    return (text_[0] if text_ else type(error).__name__)[:300]


# Its own thread, not the default executor the frame writer commits in: a database that hangs
# on connect must not tie up threads the writer needs. One check at a time; a probe arriving
# while the previous check still waits waits on that same check.
_executor = ThreadPoolExecutor(max_workers=2, thread_name_prefix="health")
_running: weakref.WeakKeyDictionary[Engine, Future] = weakref.WeakKeyDictionary()


async def check_database(engine: Engine, timeout_s: float) -> str:
    future = _running.get(engine)
    if future is None or future.done():
        future = _running[engine] = _executor.submit(_ping_database, engine)
    try:
        await asyncio.wait_for(asyncio.shield(asyncio.wrap_future(future)), timeout_s)
    except TimeoutError:
        return f"no answer within {timeout_s:g} s"
    except Exception as error:  # refused, wrong port, bad credentials, missing database...
        return f"unreachable: {_first_line(error)}"
    return "ok"


async def check_redis(bus, timeout_s: float) -> str:
    try:
        await asyncio.wait_for(bus.ping(), timeout_s)
    except TimeoutError:
        return f"no answer within {timeout_s:g} s"
    except Exception as error:
        return f"unreachable: {_first_line(error)}"
    return "ok"


async def readiness(engine: Engine, bus, timeout_s: float) -> Readiness:
    checks = {"database": await check_database(engine, timeout_s)}
    if bus is not None and bus.configured:
        checks["redis"] = await check_redis(bus, timeout_s)
    return Readiness(all(v == "ok" for v in checks.values()), checks)
