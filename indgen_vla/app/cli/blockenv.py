"""``indgen blockenv sample|train|eval|reproduce|ablate``: a passthrough subcommand whose sub-parsers and handlers
are here; the work is the BlockEnv study's (``indgen_vla.app.blockenv``). Importing this module does not import
torch."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from indgen_vla.app.cli.options import IndgenParser, add_passthrough  # one-line errors, as every command
from indgen_vla.core.errors import ConfigError


def _levels(text: str) -> list[int]:
    try:
        if ":" in text:
            lo, hi = (int(x) for x in text.split(":", 1))
            return list(range(lo, hi + 1))
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ConfigError(f"levels {text!r} must look like 0:5 or 0,1,2") from None


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen blockenv`` parses its own arguments (``main``)."""
    add_passthrough(sp, "blockenv", "the toy BlockEnv benchmark: sample | train | eval | reproduce | ablate")


def main(args: argparse.Namespace) -> int:
    """Parse ``args.rest`` with the blockenv sub-parsers and run the one named."""
    return run(args.rest)


def build_parser() -> argparse.ArgumentParser:

    p = IndgenParser(prog="indgen blockenv", description="the paper's toy inductive benchmark")
    sp = p.add_subparsers(dest="cmd", required=True)
    s = sp.add_parser("sample", help="print initial grids of a level")
    s.add_argument(
        "--level", type=int, required=True, help="level k: two chains of k distractors around the goal"
    )
    s.add_argument("--n", type=int, default=1, help="how many initial grids (default 1)")
    s.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    s.add_argument("--grid-size", type=int, default=12, help="grid side G (default 12)")
    s.add_argument("--json", action="store_true", help="a JSON list of GxG integer lists")
    t = sp.add_parser("train", help="behaviour-clone one method on oracle demonstrations")
    t.add_argument(
        "--method", required=True, help="learner key, e.g. ind or rnn (docs/blockenv.md, The learners)"
    )
    t.add_argument("--levels", default="0:2", help="training levels (paper: 0:2)")
    t.add_argument(
        "--seed", type=int, default=0, help="training seed: init, demonstrations, batches (default 0)"
    )
    t.add_argument("--steps", type=int, default=2000, help="optimiser updates (default 2000)")
    t.add_argument(
        "--demos-per-level",
        type=int,
        default=300,
        help="oracle demonstrations per training level (default 300)",
    )
    t.add_argument("--grid-size", type=int, default=12, help="grid side G (default 12)")
    t.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="a variant option of the method, e.g. legal_head=local (see docs/blockenv.md)")  # fmt: skip
    t.add_argument("--out", required=True, help="checkpoint directory to write")
    e = sp.add_parser("eval", help="evaluate a checkpoint (or --method oracle) on levels")
    e.add_argument("--method", required=True, help="learner key of the checkpoint, or oracle")
    e.add_argument(
        "--checkpoint", default=None, help="directory written by 'indgen blockenv train' (not for oracle)"
    )
    e.add_argument("--levels", default="0:5", help="levels to evaluate, like 0:10 or 0,3,5 (default 0:5)")
    e.add_argument("--episodes", type=int, default=100, help="episodes per level (default 100)")
    e.add_argument(
        "--seed", type=int, default=1000, help="evaluation seed (default 1000, apart from training seeds)"
    )
    e.add_argument(
        "--grid-size",
        type=int,
        default=None,
        help="oracle grid side (default: fits the levels, >= 12); learned methods use their checkpoint's",
    )
    e.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    e.add_argument("--out", default=None, help="write results JSON here")
    r = sp.add_parser("reproduce", help="train and evaluate every method: Table 1")
    r.add_argument("--quick", action="store_true", help="a tiny smoke run of the same pipeline")
    r.add_argument(
        "--seeds", type=int, default=None, help="training seeds per method (default 3; 1 with --quick)"
    )
    r.add_argument(
        "--max-level", type=int, default=None, help="evaluate levels 0..K (default 10; 4 with --quick)"
    )
    r.add_argument(
        "--workers", type=int, default=None, help="processes training side by side (default: cores)"
    )
    r.add_argument("--resume", action="store_true", help="keep finished jobs in OUT/jobs and reuse them")
    r.add_argument("--out", required=True, help="folder for table1.json, table1.md, table1.png (and jobs/)")
    ab = sp.add_parser("ablate", help="the reduced-scale ablations of docs/results/blockenv_ablations.md")
    ab.add_argument(
        "--name", action="append", default=None, help="ablation to run (repeatable; default: all)"
    )
    ab.add_argument("--seeds", type=int, default=3, help="training seeds per ablation (default 3)")
    ab.add_argument("--results", default="docs/results/blockenv_ablations.json", help="JSON merged into")
    ab.add_argument(
        "--doc",
        default="docs/results/blockenv_ablations.md",
        help="markdown whose ablation section is rewritten",
    )
    return p


def _sample(a) -> int:
    import numpy as np

    from indgen_vla.app.blockenv.env import BlockEnvConfig
    from indgen_vla.app.blockenv.evaluate import initial_grids

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

    from indgen_vla.app.blockenv.fit import FitConfig, save_checkpoint, train

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
    from indgen_vla.app.blockenv.env import BlockEnvConfig
    from indgen_vla.app.blockenv.evaluate import evaluate_model, oracle_rollout
    from indgen_vla.core.reporting.caveats import axis_caveats
    from indgen_vla.core.stats.metrics import break_level, wilson_ci

    levels = _levels(a.levels)
    if a.method == "oracle":
        cfg = BlockEnvConfig(grid_size=a.grid_size or max(12, max(levels) + 1))
        res = {k: (int(oracle_rollout(k, a.episodes, cfg, a.seed).sum()), a.episodes) for k in levels}
    else:
        if not a.checkpoint:
            raise ConfigError(
                "--checkpoint DIR is required for learned methods (make one with 'indgen blockenv train')"
            )
        from indgen_vla.app.blockenv.fit import load_checkpoint

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
        from indgen_vla.core.runs.records import atomic_write_json

        atomic_write_json(Path(a.out), {"method": a.method, "task": task, "ci": "wilson 95%", "levels": rows,
                                        "break_level": brk, "caveats": caveats})  # fmt: skip
    return 0


def _reproduce(a) -> int:
    from indgen_vla.app.blockenv.reproduce import ReproduceConfig, reproduce

    cfg = ReproduceConfig.quick() if a.quick else ReproduceConfig()
    import dataclasses

    if a.seeds is not None:
        cfg = dataclasses.replace(cfg, seeds=tuple(range(a.seeds)))
    if a.max_level is not None:
        cfg = dataclasses.replace(cfg, eval_levels=tuple(range(a.max_level + 1)))
    workers = a.workers if a.workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    result = reproduce(cfg, Path(a.out), log=lambda m: print(m, file=sys.stderr, flush=True), workers=workers,
                       resume=a.resume)  # fmt: skip
    from indgen_vla.app.blockenv.reproduce import render_markdown

    print(render_markdown(result))
    print(f"wrote {a.out}/table1.json, table1.md, table1.png")
    return 0


def _ablate(a) -> int:
    import dataclasses

    from indgen_vla.app.blockenv.ablate import ABLATIONS, AblationScale, ablate
    from indgen_vla.core.registry import lookup

    names = a.name or list(ABLATIONS)
    for n in names:
        lookup("BlockEnv ablation", n, ABLATIONS)
    scale = dataclasses.replace(AblationScale(), seeds=tuple(range(a.seeds)))
    ablate(names, scale, Path(a.results), Path(a.doc) if a.doc else None,
           log=lambda m: print(m, file=sys.stderr, flush=True))  # fmt: skip
    print(f"wrote {a.results}" + (f" and the ablation section of {a.doc}" if a.doc else ""))
    return 0


def run(argv: list[str]) -> int:
    """``indgen blockenv ARGV...``: parse with the blockenv sub-parsers, run the one named."""
    a = build_parser().parse_args(argv)
    handlers = {"sample": _sample, "train": _train, "eval": _eval, "reproduce": _reproduce, "ablate": _ablate}
    return handlers[a.cmd](a)
