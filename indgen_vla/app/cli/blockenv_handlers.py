"""The handlers of ``indgen blockenv sample|train|eval|reproduce|ablate`` (their parsers: ``cli/blockenv.py``): each
turns the parsed flags into a call of the BlockEnv study (``indgen_vla.app.blockenv``) and prints the result."""

from __future__ import annotations

import dataclasses
import json
import os
import sys
from pathlib import Path

import numpy as np

from indgen_vla.app.blockenv.ablate import ABLATIONS, AblationScale, ablate
from indgen_vla.app.blockenv.env import BlockEnvConfig
from indgen_vla.app.blockenv.evaluate import evaluate_model, initial_grids, oracle_rollout
from indgen_vla.app.blockenv.fit import FitConfig, load_checkpoint, save_checkpoint, train
from indgen_vla.app.blockenv.reproduce import ReproduceConfig, render_markdown, reproduce
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.registry import lookup
from indgen_vla.core.reporting.caveats import axis_caveats
from indgen_vla.core.runs.records import atomic_write_json
from indgen_vla.core.stats.metrics import break_level, wilson_ci


def _levels(text: str) -> list[int]:
    try:
        if ":" in text:
            lo, hi = (int(x) for x in text.split(":", 1))
            return list(range(lo, hi + 1))
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ConfigError(f"levels {text!r} must look like 0:5 or 0,1,2") from None


def _sample(a) -> int:
    if a.n < 1:
        raise ConfigError(f"--n must be >= 1, got {a.n}")
    cfg = BlockEnvConfig(grid_size=a.grid_size)
    cfg.check_level(a.level)
    grids = initial_grids(a.level, a.n, cfg, a.seed)
    if a.json:
        print(json.dumps(grids.astype(int).tolist()))
    else:
        for g in grids:
            print("\n".join("".join(".#G"[v] for v in row) for row in np.asarray(g)) + "\n")
    return 0


def _options(items: list[str]) -> dict:
    """KEY=VALUE strings -> options; values are read as JSON (numbers, true/false) or kept as text."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--option {item!r} must look like KEY=VALUE, e.g. legal_head=local")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def _train(a) -> int:
    from rich.progress import Progress

    cfg = FitConfig(a.method, seed=a.seed, grid_size=a.grid_size, train_levels=tuple(_levels(a.levels)),
                      steps=a.steps, demos_per_level=a.demos_per_level, extra=_options(a.option))  # fmt: skip
    print(f"training {a.method}: {cfg.demos_per_level} oracle demos per level {list(cfg.train_levels)}, "
          f"{cfg.steps} updates", file=sys.stderr, flush=True)  # fmt: skip
    with Progress(transient=True) as prog:
        task = prog.add_task(f"training {a.method}", total=cfg.steps)
        model, _ = train(
            cfg,
            progress=lambda i, loss: prog.update(
                task, completed=i + 1, description=f"training {a.method} loss {loss:.3f}"
            ),
        )
    path = save_checkpoint(model, cfg, Path(a.out))
    print(f"saved {a.method} checkpoint to {path}")
    return 0


def _eval(a) -> int:
    levels = _levels(a.levels)
    if a.method == "oracle":
        cfg = BlockEnvConfig(grid_size=a.grid_size or max(12, max(levels) + 1))
        res = {k: (int(oracle_rollout(k, a.episodes, cfg, a.seed).sum()), a.episodes) for k in levels}
    else:
        if not a.checkpoint:
            raise ConfigError(
                "--checkpoint DIR is required for learned methods (make one with 'indgen blockenv train')"
            )

        model, tc = load_checkpoint(Path(a.checkpoint))
        if tc.method != a.method:
            raise ConfigError(f"checkpoint {a.checkpoint} holds a {tc.method!r} model, not {a.method!r}")
        cfg = BlockEnvConfig(grid_size=tc.grid_size)
        res = evaluate_model(model, a.method, levels, a.episodes, cfg, a.seed, train_cfg=tc)
    rows = []
    for k, (s, n) in res.items():
        lo, hi = wilson_ci(s, n)
        rows.append({"level": k, "successes": s, "n": n, "rate": s / n, "ci_low": lo, "ci_high": hi})
    task = f"BlockEnv {cfg.grid_size}×{cfg.grid_size}"
    caveats = axis_caveats(a.method, "k", {"levels": rows, "pooled_tasks": [task]}, a.gamma, "wilson")
    for line in caveats:  # first: what these episodes cannot show (a method failing L0, too few episodes)
        print(line.replace("**", ""))
    print(f"{a.method} on task {task}, seed {a.seed}: success per level with Wilson 95 % CI")
    for r in rows:
        print(f"L{r['level']}: {100 * r['rate']:5.1f}%  [{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]  "
              f"(n={r['n']})")  # fmt: skip
    brk = break_level({r["level"]: r["rate"] for r in rows}, a.gamma)
    print(f"break level (gamma {a.gamma}, observed rate): {'none in range' if brk is None else f'L{brk}'}")
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)

        atomic_write_json(Path(a.out), {"method": a.method, "task": task, "ci": "wilson 95%", "levels": rows,
                                        "break_level": brk, "caveats": caveats})  # fmt: skip
    return 0


def _reproduce(a) -> int:
    cfg = ReproduceConfig.quick() if a.quick else ReproduceConfig()
    if a.seeds is not None:
        cfg = dataclasses.replace(cfg, seeds=tuple(range(a.seeds)))
    if a.max_level is not None:
        cfg = dataclasses.replace(cfg, eval_levels=tuple(range(a.max_level + 1)))
    workers = a.workers if a.workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    result = reproduce(cfg, Path(a.out), log=lambda m: print(m, file=sys.stderr, flush=True), workers=workers,
                       resume=a.resume)  # fmt: skip

    print(render_markdown(result))
    print(f"wrote {a.out}/table1.json, table1.md, table1.png")
    return 0


def _ablate(a) -> int:
    names = a.name or list(ABLATIONS)
    for n in names:
        lookup("BlockEnv ablation", n, ABLATIONS)
    scale = dataclasses.replace(AblationScale(), seeds=tuple(range(a.seeds)))
    ablate(names, scale, Path(a.results), Path(a.doc) if a.doc else None,
           log=lambda m: print(m, file=sys.stderr, flush=True))  # fmt: skip
    print(f"wrote {a.results}" + (f" and the ablation section of {a.doc}" if a.doc else ""))
    return 0


HANDLERS = {"sample": _sample, "train": _train, "eval": _eval, "reproduce": _reproduce, "ablate": _ablate}
