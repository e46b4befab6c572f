"""The local alarm: an Emergency the backend has not acknowledged within `after_s` (it is
unreachable, or does not commit) is announced on the robot itself: an ERROR log line and the
configured hook command. When the backend acknowledges the Emergency frames the alarm clears
(log and hook again).

The hook is run without a shell (split like a shell command line) with these variables added to
its environment: VIGIL_ALARM_STATE (raised|cleared), VIGIL_ALARM_ROBOT, VIGIL_ALARM_TRANSPORT,
VIGIL_ALARM_SINCE (Unix time of the oldest unacknowledged Emergency frame), VIGIL_ALARM_REASON.
"""

from __future__ import annotations

import asyncio
import logging
import os
import shlex
import time
from collections.abc import Callable
from enum import StrEnum

from robot_agent.outbox import Outbox
from vigil.states import StateMachine

log = logging.getLogger(__name__)
HOOK_TIMEOUT_S = 10.0


class AlarmState(StrEnum):
    QUIET = "quiet"
    RAISED = "raised"


LOCAL_ALARM = StateMachine(
    AlarmState,
    actions={
        "raise": {AlarmState.QUIET: AlarmState.RAISED},
        "clear": {AlarmState.RAISED: AlarmState.QUIET},
    },
    attribute="state",
    initial=AlarmState.QUIET,
    subject="local alarm",
)


class LocalAlarm:
    def __init__(
        self,
        robot_id: str,
        outbox: Outbox,
        problem: Callable[[], str | None],
        transport: Callable[[], str | None],
        after_s: float = 3.0,
        hook: str | None = None,
        period_s: float = 0.25,
    ) -> None:
        self.robot_id = robot_id
        self.outbox = outbox
        self.problem = problem
        self.transport = transport
        self.after_s = after_s
        self.hook = shlex.split(hook) if hook else None
        self.period_s = period_s
        LOCAL_ALARM.start(self)
        self.raised_count = 0
        self._hooks: set[asyncio.Task] = set()

    async def run(self) -> None:
        while True:
            self.check()
            await asyncio.sleep(self.period_s)

    def check(self, now: float | None = None) -> AlarmState:
        now = time.time() if now is None else now
        oldest = self.outbox.oldest_unacked_emergency()
        if self.state == AlarmState.QUIET and oldest is not None and now - oldest >= self.after_s:
            reason = self.problem() or "the backend did not acknowledge the Emergency frames"
            LOCAL_ALARM.act(self, "raise")
            self.raised_count += 1
            log.error(
                "LOCAL ALARM robot %s: Emergency since %s not acknowledged by the backend for "
                "%.1f s (%s)",
                self.robot_id,
                time.strftime("%H:%M:%S", time.localtime(oldest)),
                now - oldest,
                reason,
            )
            self._run_hook("raised", oldest, reason)
        elif self.state == AlarmState.RAISED and oldest is None:
            LOCAL_ALARM.act(self, "clear")
            log.warning(
                "local alarm cleared, robot %s: the backend acknowledged the Emergency frames",
                self.robot_id,
            )
            self._run_hook("cleared", None, "acknowledged by the backend")
        return self.state

    def _run_hook(self, state: str, since: float | None, reason: str) -> None:
        if not self.hook:
            return
        env = {
            **os.environ,
            "VIGIL_ALARM_STATE": state,
            "VIGIL_ALARM_ROBOT": self.robot_id,
            "VIGIL_ALARM_TRANSPORT": self.transport() or "",
            "VIGIL_ALARM_SINCE": "" if since is None else f"{since:.3f}",
            "VIGIL_ALARM_REASON": reason,
        }
        spawn_hook(self.hook, env, state, self._hooks)


def spawn_hook(hook: list[str], env: dict[str, str], label: str, tasks: set) -> None:
    """Run the hook command in the background (no shell, killed after HOOK_TIMEOUT_S)."""
    task = asyncio.get_running_loop().create_task(_hook(hook, env, label))
    tasks.add(task)
    task.add_done_callback(tasks.discard)


async def _hook(hook: list[str], env: dict[str, str], state: str) -> None:
    try:
        process = await asyncio.create_subprocess_exec(*hook, env=env)
    except OSError as error:
        log.error("alarm hook %s could not be started: %s", hook[0], error)
        return
    try:
        code = await asyncio.wait_for(process.wait(), HOOK_TIMEOUT_S)
    except TimeoutError:
        process.kill()
        log.error("alarm hook %s (%s) ran over %.0f s: killed", hook[0], state, HOOK_TIMEOUT_S)
        return
    if code != 0:
        log.error("alarm hook %s (%s) failed with exit code %d", hook[0], state, code)
