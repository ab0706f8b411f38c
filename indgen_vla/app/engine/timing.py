"""What an ``evaluate`` session's own clocks saw, for ``indgen budget --timing RUN``: counters the coordinator and
the workers' replies feed (``act`` seconds per batch size, rounds, the simulator's seconds per control step, scene
builds and resets), written into the manifest's ``timing`` when the session ends (docs/budget.md)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field


@dataclass
class SessionClock:
    """One process's counters; ``evaluate`` resets them when it starts and writes them when it ends."""

    entered: float = 0.0  # time.monotonic() when evaluate() was entered
    process_age_s: float = 0.0  # seconds the process had lived by then (interpreter start, imports, CLI)
    rollout_started: float | None = None
    rollout_ended: float | None = None
    act: dict[int, list[float]] = field(default_factory=dict)  # rows per act -> [calls, seconds]
    rounds: int = 0
    replies: int = 0
    wait_s: float = 0.0  # the coordinator blocked on workers
    loop_s: float = 0.0  # the coordinator's rounds, waits included
    episodes: int = 0
    steps: int = 0
    sim_s: float = 0.0  # worker seconds executing chunk slices (physics and the renders read)
    reset_s: float = 0.0  # worker seconds resetting episodes, scene builds included
    build_s: float = 0.0
    builds: int = 0

    def note_act(self, rows: int, seconds: float) -> None:
        entry = self.act.setdefault(int(rows), [0, 0.0])
        entry[0] += 1
        entry[1] += seconds

    def note_episode(self, t) -> None:
        """A finished episode's worker-side seconds (``rollout.Transition``)."""
        self.episodes += 1
        self.steps += int(t.steps)
        self.sim_s += float(getattr(t, "sim_s", 0.0))
        self.reset_s += float(getattr(t, "reset_s", 0.0))
        self.build_s += float(getattr(t, "build_s", 0.0))
        self.builds += int(getattr(t, "builds", 0))

    def rollout(self, started: bool) -> None:
        now = time.monotonic()
        if started:
            self.rollout_started = self.rollout_started or now
        else:
            self.rollout_ended = now

    def record(self, *, workers: int, processes: int, pipeline: bool, batched: bool | None, replan: int | None,
               device: str, backend: str) -> dict:  # fmt: skip
        """The manifest's ``timing``: this session's seconds from process start to the report, and the counters."""
        end = time.monotonic()
        start = self.rollout_started or end
        stop = self.rollout_ended or start
        return {
            "process_start_to_evaluate_s": round(self.process_age_s, 3),
            "startup_s": round(start - self.entered, 3),
            "rollout_s": round(stop - start, 3),
            "end_s": round(end - stop, 3),
            "workers": workers, "processes": processes, "pipeline": pipeline, "batched": batched,
            "replan_steps": replan, "device": device, "backend": backend, "cores": os.cpu_count() or 1,
            "load_avg_1m": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None,
            "episodes": self.episodes, "steps": self.steps, "sim_s": round(self.sim_s, 4),
            "reset_s": round(self.reset_s, 4), "build_s": round(self.build_s, 4), "builds": self.builds,
            "act": {str(k): [int(c), round(s, 5)] for k, (c, s) in sorted(self.act.items())},
            "rounds": self.rounds, "replies": self.replies, "wait_s": round(self.wait_s, 4),
            "loop_s": round(self.loop_s, 4),
        }  # fmt: skip


CLOCK = SessionClock()


def process_age_s() -> float:
    """Seconds since this process started (Linux /proc; 0 elsewhere): the interpreter's start and imports."""
    try:
        ticks = os.sysconf("SC_CLK_TCK")
        with open("/proc/self/stat") as f:
            started = int(f.read().rsplit(")", 1)[1].split()[19]) / ticks
        with open("/proc/uptime") as f:
            return max(0.0, float(f.read().split()[0]) - started)
    except (OSError, ValueError, IndexError):
        return 0.0


def start_session() -> SessionClock:
    """Fresh counters for an ``evaluate`` session in this process."""
    global CLOCK
    CLOCK = SessionClock(entered=time.monotonic(), process_age_s=process_age_s())
    return CLOCK
