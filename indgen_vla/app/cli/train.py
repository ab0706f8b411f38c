"""``indgen train``: its parser (over the passthrough arguments); the handler trains
(``indgen_vla.app.regimes.train.train_policy``) and prints where the checkpoint is."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen train`` parses its own arguments (``main``)."""
    add_passthrough(sp, "train", "train a small LeRobot policy (ACT/Diffusion) on one or more datasets")


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    import json
    from pathlib import Path

    from indgen_vla.app.regimes.train import (
        DEFAULT_REPO_ID,
        INFO_FILE,
        POLICIES,
        TrainConfig,
        train_policy,
    )
    from indgen_vla.app.regimes.train_eval import add_eval_options, eval_hook
    from indgen_vla.core.protocol.training_support import cells_from_json, support_text

    p = IndgenParser(prog="indgen train", description="train a small lerobot policy on indgen datasets")
    p.add_argument(
        "datasets", nargs="+", help="LeRobotDataset root directories (e.g. human and MimicGen demos)"
    )
    p.add_argument("--out", required=True,
                   help="checkpoint directory: new, or an unfinished one to resume with the same arguments")  # fmt: skip
    p.add_argument("--policy", default="act", choices=POLICIES, help="lerobot policy type to train")
    p.add_argument("--steps", type=int, default=TrainConfig.steps, help="optimiser updates")
    p.add_argument("--batch-size", type=int, default=TrainConfig.batch_size, help="frames per update")
    p.add_argument("--lr", type=float, default=TrainConfig.lr, help="learning rate")
    p.add_argument("--seed", type=int, default=0, help="training seed (init and batch order)")
    p.add_argument("--cameras", default="", help="comma-separated cameras to read; empty = state-only")
    p.add_argument(
        "--objects", action="store_true", help="also read the recorded object poses (low-dim; no cameras)"
    )
    p.add_argument(
        "--chunk-size", type=int, default=TrainConfig.chunk_size, help="actions predicted per chunk"
    )
    p.add_argument(
        "--n-action-steps", type=int, default=TrainConfig.n_action_steps, help="actions executed per chunk"
    )
    p.add_argument(
        "--data-regime", default="", help="label stored with the checkpoint (e.g. human, human+mimicgen)"
    )
    p.add_argument("--repo-id", default=DEFAULT_REPO_ID, help="repo id stored in the checkpoint config")
    p.add_argument("--save-every", type=int, default=None,
                   help="steps between resumable states in OUT/resume (default: every 10%% of --steps)")  # fmt: skip
    add_eval_options(p)
    a = p.parse_args(getattr(args, "rest", args))
    cameras = tuple(c for c in a.cameras.split(",") if c)
    cfg = TrainConfig(policy=a.policy, steps=a.steps, batch_size=a.batch_size, lr=a.lr, seed=a.seed,
                      cameras=cameras, objects=a.objects, chunk_size=a.chunk_size, n_action_steps=a.n_action_steps,
                      save_every=a.save_every)  # fmt: skip
    done = (Path(a.out) / INFO_FILE).is_file()
    hook = eval_hook(a, Path(a.out))
    out = train_policy(a.datasets, a.out, cfg, repo_id=a.repo_id, data_regime=a.data_regime, say=print,
                       progress=lambda s, loss: print(f"  step {s}/{cfg.steps} loss {loss:.4f}", flush=True),
                       after_step=hook)  # fmt: skip
    if done:
        return 0
    info = json.loads((out / INFO_FILE).read_text())
    print(f"trained {a.policy} for {cfg.steps} steps in {info['train_s']:.0f} s; checkpoint in {out}")
    if info["levels"]:
        print(
            f"training levels (train_info.json, read by evaluate): {support_text(cells_from_json(info['levels']))}"
        )
    return 0
