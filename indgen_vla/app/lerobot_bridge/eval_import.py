"""``indgen import lerobot-eval DIR... --out RUN``: lerobot-eval's per-episode successes as an indgen run directory, so
``report``, ``compare``, ``gate`` and ``series`` read them; the manifest's ``imported`` entry says where each episode
came from and what the file does not say (docs/lerobot.md).

Each (task_group, task_id) of each eval_info.json becomes one (task, axis, level) cell. A group that
``--env.type=indgen`` wrote (``level_env.group_name``) names its level and parameter itself: its episodes get indgen's
episode index (reset seed - first_seed) and evaluation seed, so they pair with ``indgen evaluate``'s. Any
other env's group is the level ``--axis A --level K`` says, episode i keeping its lerobot reset seed.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.app.lerobot_bridge.level_env import (
    FIRST_SEED,
    FamilyOf,
    LevelRequest,
    parse_group,
    resolve_levels,
)
from indgen_vla.core.errors import ConfigError, IndgenError, RunDirError
from indgen_vla.core.protocol.seeding import evaluation_seed
from indgen_vla.core.runs.imported import IMPORTED, EvalInfo, TaskEpisodes, read_eval_info
from indgen_vla.core.runs.records import (
    MANIFEST,
    SECTIONS,
    EpisodeRecord,
    RunDir,
    atomic_write_json,
    atomic_write_text,
)

# what an eval_info.json does not carry, so the imported rows cannot say it (docs/lerobot.md)
UNKNOWN = (
    "steps (episode lengths): recorded as 0",
    "wall_s: recorded as 0",
    "failure modes and progress (indgen reads them from privileged simulator state): not classified",
    "errors: lerobot-eval has no per-episode error status, so every episode is ok",
    "protocol fingerprint (simulator versions, horizon, cameras, policy conventions): not checked by compare/gate",
    "videos",
)


@dataclass(frozen=True)
class ImportConfig:
    """What ``indgen import lerobot-eval`` reads and writes."""

    sources: tuple[str, ...]
    out: str
    axis: str | None = None
    level: int | None = None
    seed: int | None = (
        None  # lerobot-eval's --seed, for files that record no seeds (lerobot 0.6: default 1000)
    )
    policy: str | None = None
    data_regime: str = ""

    def __post_init__(self) -> None:
        if not self.sources:
            raise ConfigError("give one or more lerobot-eval output directories to import")
        if (self.axis is None) != (self.level is None):
            raise ConfigError(
                "--axis and --level go together: which level of which axis the lerobot-eval run is"
            )
        if not self.out:
            raise ConfigError("--out is required: the run directory to write")


@dataclass
class _Cell:
    scene: str
    task: str
    axis: str
    level: int
    param: float
    rows: list[EpisodeRecord]
    source: dict
    spec: dict  # indgen's AxisSpec as a dict; {} for another env's level


def _cell(
    cfg: ImportConfig, info: EvalInfo, t: TaskEpisodes, policy: str, run_id: str, family_of: FamilyOf
) -> _Cell:
    """One task of one file as indgen episodes, with how its seeds were found."""
    ours = parse_group(t.group)
    start = FIRST_SEED if cfg.seed is None else cfg.seed
    if t.seeds is not None:
        resets, how = list(t.seeds), "recorded in eval_info.json"
    else:
        given = (
            "--seed"
            if cfg.seed is not None
            else "lerobot-eval's default --seed (pass --seed if it ran with another)"
        )
        resets = [start + i for i in range(len(t.successes))]
        how = f"not recorded (lerobot 0.6): reset seed = {start} + episode_ix, {given}"
    source = {"path": str(info.path.resolve()), "sha256": info.sha256, "format": info.format,
              "task_group": t.group, "task_id": t.task_id, "episodes": len(t.successes), "reset_seeds": how}  # fmt: skip
    if ours is not None:
        if cfg.axis is not None and (cfg.axis, cfg.level) != (ours["axis"], ours["level"]):
            raise ConfigError(f"{info.path}: task group {t.group} is indgen's {ours['axis']} level {ours['level']}, "
                              f"not --axis {cfg.axis} --level {cfg.level}; drop --axis/--level for it")  # fmt: skip
        param, spec = ours["param"], _axis_spec(ours, family_of)
        episodes = [s - ours["first_seed"] for s in resets]
        if min(episodes) < 0:
            raise RunDirError(f"{info.path}: reset seeds start at {min(resets)}, below the env's first_seed "
                              f"{ours['first_seed']}; pass the --seed lerobot-eval ran with")  # fmt: skip
        seeds = [evaluation_seed(ours["run_seed"], ours["scene"], ours["task"], e) for e in episodes]
        scene, task, axis, level = ours["scene"], ours["task"], ours["axis"], ours["level"]
        source["indgen_level"] = {**ours, "episodes": f"reset seed - {ours['first_seed']}",
                                  "seeds": f"evaluation_seed(run_seed={ours['run_seed']}, scene, task, episode)"}  # fmt: skip
    else:
        if cfg.axis is None:
            raise ConfigError(f"{info.path}: task group {t.group or '(one task)'} is not an indgen level; pass "
                              "--axis A --level K: which level of which axis this lerobot-eval run is")  # fmt: skip
        group = t.group or "lerobot"
        scene, task, axis, level = f"lerobot-eval:{group}", str(t.task_id), cfg.axis, int(cfg.level)
        param, episodes, seeds, spec = math.nan, list(range(len(resets))), resets, {}
    rows = [EpisodeRecord(run_id=run_id, policy=policy, data_regime=cfg.data_regime, scene=scene, task=task,
                          axis=axis, level=level, param=param, episode=e, seed=s, success=ok, steps=0)
            for e, s, ok in zip(episodes, seeds, t.successes, strict=True)]  # fmt: skip
    return _Cell(scene, task, axis, level, param, rows, source, spec)


def _axis_spec(level: dict, family_of: FamilyOf) -> dict:
    """The axis's spec as ``indgen evaluate`` resolves it by default, where that gives the group's parameter (else the
    env ran another step or preset, which the group does not name: only the axis's name is recorded)."""
    try:
        setups, _ = resolve_levels(LevelRequest(scene=level["scene"], task=level["task"], axis=level["axis"],
                                                level=level["level"], run_seed=level["run_seed"],
                                                allow_infeasible=True), family_of)  # fmt: skip
    except IndgenError:  # a scene or axis this machine cannot resolve: the episodes still import
        return {"name": level["axis"]}
    if abs(setups[0].param - level["param"]) > 1e-9 * (1 + abs(level["param"])):
        return {"name": level["axis"]}
    return dataclasses.asdict(setups[0].axis_spec)


def import_lerobot_eval(cfg: ImportConfig, family_of: FamilyOf) -> Path:
    """Write (or rewrite, when it holds an earlier import) the run directory ``cfg.out`` from the sources;
    ``family_of``: the edge's (API's) look-up of a group's scene family (an indgen level names its scene)."""
    infos = [read_eval_info(s) for s in cfg.sources]
    digest = hashlib.sha256("".join(i.sha256 for i in infos).encode()).hexdigest()[:12]
    policy = cfg.policy or f"lerobot-eval:{Path(cfg.sources[0]).resolve().name}"
    cells = [_cell(cfg, info, t, policy, digest, family_of) for info in infos for t in info.tasks]
    scenes = sorted({c.scene for c in cells})
    if len(scenes) > 1:
        raise ConfigError(
            f"the sources hold several scenes ({', '.join(scenes)}); import each into its own --out"
        )
    seen: dict[tuple, str] = {}
    for c in cells:
        for r in c.rows:
            if r.key in seen:
                raise ConfigError(f"{c.source['path']} and {seen[r.key]} both hold {r.axis} L{r.level:+d} task "
                                  f"{r.task} episode {r.episode}; import them into separate --out directories")  # fmt: skip
            seen[r.key] = c.source["path"]
    out = Path(cfg.out)
    if (out / MANIFEST).exists() and IMPORTED not in RunDir(out).manifest:
        raise RunDirError(f"{out} holds a run that was not imported; choose another --out")
    axes = list(dict.fromkeys(c.axis for c in cells))
    levels = {a: sorted({c.level for c in cells if c.axis == a}) for a in axes}
    tasks = sorted({c.task for c in cells})
    run_seeds = sorted({c.source["indgen_level"]["run_seed"] for c in cells if "indgen_level" in c.source})
    plan = {"policy": policy, "scene": scenes[0], "tasks": tasks, "axes": axes, "levels": levels,
            "episodes": max(len(c.rows) for c in cells), "seed": run_seeds[0] if len(run_seeds) == 1 else None,
            "data_regime": cfg.data_regime}  # fmt: skip
    manifest = {
        "run_id": digest, "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"), "policy": policy,
        "data_regime": cfg.data_regime, "scene": scenes[0], "seed": plan["seed"], "plan": plan,
        "axes": _axes(cells),
        # what indgen series' finished() and the run index read: every imported episode is planned and finished
        "resolved": {"episodes": sum(len(c.rows) for c in cells)},
        "config": {"import": "lerobot-eval", **dataclasses.asdict(cfg)},
        IMPORTED: {"from": "lerobot-eval", "sources": [c.source for c in cells], "unknown": list(UNKNOWN)
                   + ([] if cfg.policy else ["policy: eval_info.json does not name it (pass --policy)"]),
                   "pairing": "episodes pair by seed: gate and compare pair two runs only where every level holds the "
                              "same seeds"},
        "command": " ".join(["indgen", *sys.argv[1:]]) if sys.argv and "indgen" in Path(sys.argv[0]).name else "",
    }  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    run = RunDir(out)
    atomic_write_json(out / MANIFEST, manifest)
    run.rewrite(r for c in cells for r in c.rows)
    (out / SECTIONS).mkdir(exist_ok=True)
    atomic_write_text(out / SECTIONS / "imported.md", _section(manifest[IMPORTED]))
    return out


def _section(entry: dict) -> str:
    """report.md's section on where the episodes came from and what they do not say (``report.d/imported.md``)."""
    lines = ["", "## Imported episodes", "",
             "These episodes were rolled out by lerobot-eval, not by indgen evaluate (`indgen import lerobot-eval`).", "",
             "| source | task group | task id | episodes | reset seeds |", "|---|---|---|---|---|"]  # fmt: skip
    lines += [f"| {s['path']} | {s['task_group'] or '—'} | {s['task_id']} | {s['episodes']} | {s['reset_seeds']} |"
              for s in entry["sources"]]  # fmt: skip
    lines += [
        "",
        "Not in eval_info.json, so not in these rows:",
        "",
        *(f"- {u}" for u in entry["unknown"]),
        "",
    ]
    return "\n".join(lines)


def _axes(cells: Sequence[_Cell]) -> dict:
    """The manifest's ``axes``: indgen's axis spec where the level is indgen's, else only the axis's name."""
    out: dict = {}
    for c in cells:
        if c.axis not in out or (c.spec and "step" not in out[c.axis]):
            out[c.axis] = c.spec or {"name": c.axis}
    return out
