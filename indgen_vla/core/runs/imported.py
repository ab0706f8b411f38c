"""Runs whose episodes another harness rolled out (``indgen import lerobot-eval``): reading ``eval_info.json`` and
pairing two such runs by seed. Pure: reads files, writes nothing (``indgen_vla.app.lerobot_bridge.eval_import``
writes the run directory).

``lerobot-eval`` (lerobot 0.6) writes ``{"per_task": [{"task_group", "task_id", "metrics": {"sum_rewards",
"max_rewards", "successes", ...}}], "per_group": ..., "overall": {"n_episodes", "pc_success", ...}}``: per-episode
successes in episode order, no seeds (episode i was reset with ``--seed + i``). Older releases wrote one task's
``{"per_episode": [{"episode_ix", "sum_reward", "max_reward", "success", "seed"}], "aggregated": ...}``; both are read.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import RunDirError
from indgen_vla.core.runs.records import RunDir

EVAL_INFO = "eval_info.json"
IMPORTED = "imported"  # the manifest entry of an imported run: where its episodes came from, what is unknown
FORMAT_PER_TASK = "per_task (lerobot-eval, lerobot >= 0.4)"
FORMAT_PER_EPISODE = "per_episode (lerobot-eval's eval_policy, older releases)"


@dataclass(frozen=True)
class TaskEpisodes:
    """One lerobot-eval task (task_group, task_id) and its episodes in order."""

    group: str
    task_id: int
    successes: tuple[bool, ...]
    sum_rewards: tuple[float, ...]
    max_rewards: tuple[float, ...]
    seeds: tuple[int, ...] | None  # recorded seeds (older format); None: lerobot 0.6 records none


@dataclass(frozen=True)
class EvalInfo:
    """A parsed eval_info.json."""

    path: Path
    sha256: str
    format: str
    tasks: tuple[TaskEpisodes, ...]


def _bad(path: Path, what: str) -> RunDirError:
    return RunDirError(f"{path}: {what}; point at the output directory of a finished lerobot-eval run")


def _bools(path: Path, where: str, values: Any) -> tuple[bool, ...]:
    if not isinstance(values, list):
        raise _bad(path, f"{where} is {type(values).__name__}, not a list")
    for i, v in enumerate(values):
        if not isinstance(v, bool):
            raise _bad(path, f"{where}[{i}] is {v!r}, not true/false")
    return tuple(values)


def _numbers(path: Path, where: str, values: Any, n: int) -> tuple[float, ...]:
    if values is None:
        return (math.nan,) * n
    if not isinstance(values, list) or len(values) != n:
        got = len(values) if isinstance(values, list) else type(values).__name__
        raise _bad(path, f"{where} holds {got} entries but there are {n} successes (a partial file)")
    for i, v in enumerate(values):
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise _bad(path, f"{where}[{i}] is {v!r}, not a number")
    return tuple(float(v) for v in values)


def _per_task(path: Path, data: dict) -> tuple[TaskEpisodes, ...]:
    entries = data["per_task"]
    if not isinstance(entries, list) or not entries:
        raise _bad(path, "per_task is empty or not a list (no task was evaluated)")
    tasks = []
    for i, e in enumerate(entries):
        where = f"per_task[{i}]"
        if (
            not isinstance(e, dict)
            or not isinstance(e.get("task_group"), str)
            or not isinstance(e.get("metrics"), dict)
        ):
            raise _bad(path, f"{where} lacks task_group or metrics")
        tid = e.get("task_id")
        if isinstance(tid, bool) or not isinstance(tid, int):
            raise _bad(path, f"{where}.task_id is {tid!r}, not an integer")
        m = e["metrics"]
        if "successes" not in m:
            raise _bad(path, f"{where}.metrics has no successes")
        ok = _bools(path, f"{where}.metrics.successes", m["successes"])
        if not ok:
            raise _bad(path, f"{where}.metrics.successes is empty (no episode finished)")
        tasks.append(TaskEpisodes(e["task_group"], tid, ok, _numbers(path, f"{where}.metrics.sum_rewards",
                                  m.get("sum_rewards"), len(ok)),
                                  _numbers(path, f"{where}.metrics.max_rewards", m.get("max_rewards"), len(ok)),
                                  None))  # fmt: skip
    keys = [(t.group, t.task_id) for t in tasks]
    if len(set(keys)) != len(keys):
        raise _bad(path, "per_task lists a (task_group, task_id) twice")
    overall = data.get("overall")
    total = sum(len(t.successes) for t in tasks)
    if (
        isinstance(overall, dict)
        and isinstance(overall.get("n_episodes"), int)
        and overall["n_episodes"] != total
    ):
        raise _bad(path, f"overall.n_episodes is {overall['n_episodes']} but per_task holds {total} episodes "
                         "(a partial file)")  # fmt: skip
    return tuple(tasks)


def _per_episode(path: Path, data: dict) -> tuple[TaskEpisodes, ...]:
    rows = data["per_episode"]
    if not isinstance(rows, list) or not rows:
        raise _bad(path, "per_episode is empty or not a list (no episode finished)")
    ok, sums, maxes, seeds = [], [], [], []
    for i, r in enumerate(rows):
        where = f"per_episode[{i}]"
        if not isinstance(r, dict):
            raise _bad(path, f"{where} is not an object")
        missing = [k for k in ("episode_ix", "success", "seed") if k not in r]
        if missing:
            raise _bad(path, f"{where} lacks {', '.join(missing)}")
        if r["episode_ix"] != i:
            raise _bad(
                path,
                f"{where}.episode_ix is {r['episode_ix']!r}, expected {i} (episodes missing or out of order)",
            )
        if not isinstance(r["success"], bool):
            raise _bad(path, f"{where}.success is {r['success']!r}, not true/false")
        if isinstance(r["seed"], bool) or not isinstance(r["seed"], int):
            raise _bad(path, f"{where}.seed is {r['seed']!r}: lerobot-eval ran unseeded, so its episodes cannot be "
                             "paired or placed; re-run it with --seed")  # fmt: skip
        ok.append(r["success"])
        sums.append(r.get("sum_reward", math.nan))
        maxes.append(r.get("max_reward", math.nan))
        seeds.append(r["seed"])
    if len(set(seeds)) != len(seeds):
        raise _bad(path, "per_episode lists a seed twice")
    agg = data.get("aggregated")
    if isinstance(agg, dict) and isinstance(agg.get("pc_success"), int | float):
        if abs(agg["pc_success"] - 100 * sum(ok) / len(ok)) > 1e-6:
            raise _bad(path, f"aggregated.pc_success is {agg['pc_success']} but per_episode gives "
                             f"{100 * sum(ok) / len(ok):.4g} (a partial file)")  # fmt: skip
    n = len(ok)
    return (TaskEpisodes("", 0, tuple(ok), _numbers(path, "per_episode sum_reward", sums, n),
                         _numbers(path, "per_episode max_reward", maxes, n), tuple(seeds)),)  # fmt: skip


def read_eval_info(src: str | Path) -> EvalInfo:
    """Parse a lerobot-eval output directory (or its eval_info.json); one line naming what is wrong otherwise."""
    p = Path(src)
    path = p / EVAL_INFO if p.is_dir() else p
    if not path.is_file():
        raise RunDirError(f"{p} holds no {EVAL_INFO}; pass lerobot-eval's --output_dir of a finished run")
    raw = path.read_bytes()
    try:
        data = json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise _bad(path, f"is not valid JSON ({e}), e.g. cut short while written") from None
    if not isinstance(data, dict):
        raise _bad(path, f"holds a JSON {type(data).__name__}, not lerobot-eval's object")
    if "per_task" in data:
        fmt, tasks = FORMAT_PER_TASK, _per_task(path, data)
    elif "per_episode" in data:
        fmt, tasks = FORMAT_PER_EPISODE, _per_episode(path, data)
    else:
        raise _bad(
            path, "has neither per_task nor per_episode: not an eval_info.json written by lerobot-eval"
        )
    return EvalInfo(path, hashlib.sha256(raw).hexdigest(), fmt, tasks)


def check_paired_by_seed(
    manifests: tuple[dict, dict], episodes: tuple[Any, Any], labels: tuple[str, str]
) -> None:
    """Two runs of which one or both were imported pair only when each (task, axis, level) holds the same seeds in
    both: refuse anything else in one line (the gate would otherwise fall back to an unpaired test silently)."""
    if not any(IMPORTED in m for m in manifests):
        return
    cells = []
    for e in episodes:
        ok = e[e["status"] == "ok"]
        cells.append({k: set(g["seed"].astype(int)) for k, g in ok.groupby(["task", "axis", "level"])})
    a, b = cells
    for key in sorted(set(a) | set(b), key=str):
        sa, sb = a.get(key, set()), b.get(key, set())
        if sa != sb:
            only_a, only_b = sorted(sa - sb), sorted(sb - sa)
            task, axis, level = key
            raise RunDirError(
                f"imported runs pair episodes by seed, but at {axis} L{int(level):+d} (task {task}) "
                f"{len(only_a)} episode(s) of {labels[0]} (seeds {_few(only_a)}) and {len(only_b)} of {labels[1]} "
                f"(seeds {_few(only_b)}) have no partner; run lerobot-eval with the same --seed and "
                "--eval.n_episodes for both, or pass --test boschloo to compare them unpaired"
            )


def refuse_unpaired_imports(path_a: str, path_b: str) -> None:
    """``check_paired_by_seed`` of two run directories, for the commands that pair episodes (gate, compare)."""
    runs = (RunDir.open(path_a), RunDir.open(path_b))
    if any(IMPORTED in r.manifest for r in runs):
        check_paired_by_seed((runs[0].manifest, runs[1].manifest), (runs[0].episodes(), runs[1].episodes()),
                             (path_a, path_b))  # fmt: skip


def _few(seeds: list[int]) -> str:
    return "none" if not seeds else ", ".join(map(str, seeds[:3])) + (", ..." if len(seeds) > 3 else "")
