"""The ``indgen`` command line: argparse front end that dispatches to lazily imported capabilities.

Every subcommand handler is ``"package.module:function"`` taking the parsed ``argparse.Namespace`` and
returning an exit code, so ``indgen --help`` never imports torch, robosuite or lerobot.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import re
import sys
from collections.abc import Sequence

from indgen_vla import __version__
from indgen_vla.errors import EXIT_SIGTERM, IndgenError, Terminated
from indgen_vla.interrupts import interrupted_message, sigterm_raises

# subcommand -> "package.module:function" handler, imported only when that subcommand runs
HANDLERS: dict[str, str] = {
    "evaluate": "indgen_vla.engine.cli:evaluate_main",
    "certify": "scenes.certify:certify_main",
    "preview": "scenes.preview:preview_main",
    "report": "indgen_vla.report:report_main",
    "merge": "indgen_vla.engine.merge:merge_main",
    "compare": "indgen_vla.compare:compare_main",
    "reference": "indgen_vla.reference:reference_main",
    "serve": "policy_wrappers.serve:serve_main",
    "scenes": "scenes.catalog:scenes_main",
    "axes": "scenes.catalog:axes_main",
    "policies": "policy_wrappers.registry:policies_main",
    "setup": "scenes.robocasa.setup:setup_main",
    "blockenv": "indgen_vla.blockenv.cli:blockenv_main",
    "demos": "indgen_vla.regimes.demos:demos_main",
    "mimicgen": "indgen_vla.regimes.mimicgen:mimicgen_main",
    "train": "indgen_vla.regimes.train:train_main",
    "real": "indgen_vla.real_policy:real_main",
}


class IndgenParser(argparse.ArgumentParser):
    """argparse that suggests the closest subcommand or choice on a typo, in one line, and reads
    level ranges such as ``--levels -3:3`` or ``--levels -2,0,2`` as values, not as options."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\d+(\.\d+)?$|^-\d+:-?\d+$|^-\d+(,-?\d+)+$")

    def error(self, message: str) -> None:  # type: ignore[override]
        import difflib

        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            choices = re.findall(r"'([^']*)'", m.group(2)) or [c.strip() for c in m.group(2).split(",")]
            close = difflib.get_close_matches(m.group(1), choices, n=1, cutoff=0.5)
            if close:
                message += f"; did you mean {close[0]!r}?"
        self.exit(2, f"{self.prog}: error: {message}\n")


def add_level_options(p: argparse.ArgumentParser, levels_default: str = "default: the axis range") -> None:
    """--levels, --step and --axes-preset: which levels run and how far apart (evaluate, certify, preview and demos
    alike; ``levels_default`` says what an omitted --levels means there)."""
    p.add_argument(
        "--levels",
        default=None,
        help=f"inclusive range like -3:3 or list like 0,1,2 ({levels_default})",
    )
    p.add_argument("--step", type=float, default=None, help="override the axis's atomic step size")
    p.add_argument(
        "--axes-preset",
        default=None,
        metavar="NAME|PATH",
        help="shipped axes preset (paper, quick) or YAML path: steps and level ranges, compositions' components too",
    )


def _workers(text: str) -> int | str:
    """``--workers``: a number, or ``auto`` (the Ray backend follows its cluster's CPUs)."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got {text!r}") from None


def _add_evaluate(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser("evaluate", help="run a policy along one or more axes and write a run directory")
    p.add_argument("--policy", help="policy spec, e.g. lerobot:HUB_ID, openpi:ws://HOST:PORT, standin:oracle")
    p.add_argument("--scene", help="scene name (see 'indgen scenes')")
    p.add_argument(
        "--task", default=None, help="task of the scene, or 'all' (default: the scene's first task)"
    )
    p.add_argument("--axis", help="axis or comma list of axes (see 'indgen axes')")
    add_level_options(p)
    p.add_argument(
        "--episodes", type=int, default=None, help="episodes per level (default 50; the cap with --adaptive)"
    )
    p.add_argument(
        "--adaptive",
        choices=["kstar", "curve", "until-failure"],
        default=None,
        help="run episodes in rounds and stop a level once a sequential test decides it (kstar: also skip levels "
        "past a decided break; curve: decide every level); until-failure: the paper's real-robot design, "
        "--episodes per level, levels in order until the first observed rate < γ (no test); docs/adaptive.md",
    )
    p.add_argument(
        "--adaptive-delta", type=float, default=None, help="indifference half-width around γ (default 0.1)"
    )
    p.add_argument(
        "--adaptive-alpha", type=float, default=None, help="error rate of each verdict, α = β (default 0.025)"
    )
    p.add_argument("--round-size", type=int, default=None, help="episodes between two looks (default 5)")
    p.add_argument("--workers", type=_workers, default=None,
                   help="worker processes (default: number of cores); with --backend ray the simulator actors, "
                   "or auto: as many as the cluster's CPUs hold, following nodes that join or leave")  # fmt: skip
    p.add_argument(
        "--device", default=None, help="where in-process policies run: cpu, cuda, cuda:N (default cpu)"
    )
    p.add_argument(
        "--precision",
        choices=["fp32", "bf16"],
        default=None,
        help="bf16: autocast forward (lerobot: policies)",
    )
    p.add_argument(
        "--compile",
        choices=["off", "default", "reduce-overhead", "max-autotune"],
        default=None,
        help="torch.compile the policy's per-call forward (lerobot: policies; reduce-overhead = CUDA graphs, "
        "needs --device cuda); the first call compiles, ~/.cache/indgen/inductor keeps it for the next run",
    )
    p.add_argument(
        "--pipeline",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="two environments per worker: one steps while the policy computes the other's chunk (default off)",
    )
    p.add_argument(
        "--share-t0",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="run level 0 once per task for the axes whose level 0 is the same environment; each such axis reports "
        "those episodes as its own (episodes.parquet shared_from; default on, --adaptive too)",
    )
    p.add_argument(
        "--backend",
        choices=["local", "ray"],
        default=None,
        help="local worker processes or Ray (default local)",
    )
    p.add_argument("--seed", type=int, default=None, help="run seed (default 0)")
    p.add_argument("--max-steps", type=int, default=None, help="override the scene's episode length")
    p.add_argument(
        "--replan-steps", type=int, default=None, help="actions executed per chunk (default: the policy's)"
    )
    p.add_argument(
        "--image-size", type=int, default=None, help="rendered image side in pixels (default: the policy's)"
    )
    p.add_argument("--video", action="store_true", help="write mp4 videos of episodes")
    p.add_argument(
        "--video-per-level", type=int, default=None, help="videos per level when --video (default 1)"
    )
    p.add_argument(
        "--data-regime", default=None, help="label of the training data regime, e.g. h-only or h+mg"
    )
    p.add_argument("--gamma", type=float, default=None, help="break threshold for the report (default 0.2)")
    p.add_argument(
        "--allow-infeasible", action="store_true", help="evaluate levels the oracle did not certify"
    )
    p.add_argument(
        "--smoke",
        action="store_true",
        help="run an image policy on placeholder assets (RoboCasa's boxes) anyway; recorded as not a measurement",
    )
    p.add_argument(
        "--trust-remote-code", action="store_true", help="allow checkpoints that ship their own code"
    )
    p.add_argument(
        "--allow-protocol-mismatch",
        action="store_true",
        help="resume a run although its protocol fingerprint changed in a field that changes outcomes "
        "(simulator versions, assets, horizon, cameras, render backend, policy conventions); the manifest lists it",
    )
    p.add_argument(
        "--server-patience",
        type=float,
        default=None,
        help="seconds to keep reconnecting to an unreachable policy server before stopping (default 600)",
    )
    p.add_argument(
        "--config",
        default=None,
        help="shipped preset name (configs/paper) or YAML path; flags override it",
    )
    p.add_argument("--out", help="run directory (re-run the same command to resume)")


def _add_certify(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser("certify", help="certify every level of an axis with the privileged oracle")
    p.add_argument("--scene", required=True, help="scene to certify (see 'indgen scenes')")
    p.add_argument("--task", default=None, help="task of the scene, or 'all' (default: the first task)")
    p.add_argument("--axis", required=True, help="axis or composition, e.g. pick_y or pick_y+distractor")
    add_level_options(p)
    p.add_argument(
        "--episodes", type=int, default=None, help="most episodes per level (default: the 59 the rule needs)"
    )
    p.add_argument(
        "--threshold", type=float, default=None, help="oracle success rate to certify (default 0.95)"
    )
    p.add_argument("--seed", type=int, default=0, help="certification seed (default 0)")
    p.add_argument("--max-steps", type=int, default=None, help="override the scene's episode length")
    p.add_argument("--workers", type=int, default=1, help="processes, one level each (physics only)")
    p.add_argument(
        "--out", default=None, help="folder for certify.json (default: where evaluate looks; resumes there)"
    )


def _add_preview(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser(
        "preview",
        help="render each level's first observation into one labelled sheet (check an axis before a run)",
    )
    p.add_argument("--scene", required=True, help="scene (see 'indgen scenes')")
    p.add_argument("--task", default=None, help="task of the scene (default: the scene's first task)")
    p.add_argument(
        "--axis", required=True, help="axis, composition or comma list (one row each), e.g. pick_y"
    )
    add_level_options(p)
    p.add_argument(
        "--camera", default=None, help="camera to show (default: the scene's first, e.g. agentview)"
    )
    p.add_argument("--size", type=int, default=256, help="image side in pixels (default 256)")
    p.add_argument("--episode", type=int, default=0, help="episode whose initial state to show (default 0)")
    p.add_argument("--seed", type=int, default=0, help="run seed, as evaluate's --seed (default 0)")
    p.add_argument("--out", required=True, help="image file: .png, .pdf, .svg or .jpg")


def _add_report(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser("report", help="summary.json, report.md and plots for one or more run directories")
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="run directories written by 'indgen evaluate'")
    p.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    p.add_argument(
        "--ci",
        choices=["wilson", "clopper-pearson"],
        default="wilson",
        help="95%% interval of each level's success rate (default wilson; clopper-pearson is exact, wider)",
    )
    p.add_argument(
        "--margin", type=float, default=None, metavar="M",
        help="also test, per level, whether the change from level 0 lies within ±M (paired equivalence test, e.g. "
        "0.1 for ±10 points): the only way the report says \"no change\"",
    )  # fmt: skip
    p.add_argument(
        "--out", default=None, help="where to put the multi-run overlay (default: FIRST_RUN/overlay)"
    )


def _add_merge(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser(
        "merge",
        help="merge the shards of one protocol (evaluate runs split by --task or --axis) into one run directory",
        description="Shards of one evaluate command split over a cluster (one job per task or axis) as one ordinary "
        "run directory: the union of their plans and every finished episode, for report, compare, reference and a "
        "resume. Refuses shards that are not parts of one protocol (plan, fingerprint, outcomes); never writes into "
        "a shard.",
    )
    p.add_argument(
        "runs",
        nargs="+",
        metavar="RUN_DIR",
        help="the shards' run directories (written by 'indgen evaluate')",
    )
    p.add_argument("--out", required=True, help="the merged run directory (new, or an empty directory)")


def _add_compare(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser(
        "compare",
        help="per-level exact tests between two runs (paired when seeds match), or two axes (--axes), Holm",
    )
    p.add_argument("run_a", metavar="RUN_A", nargs="?", help="run directory A (or use --a for a group)")
    p.add_argument("run_b", metavar="RUN_B", nargs="?", help="run directory B (or use --b for a group)")
    p.add_argument(
        "--a", nargs="+", metavar="RUN", help="group A: one run per training seed (paired with --b by order)"
    )
    p.add_argument(
        "--b", nargs="+", metavar="RUN", help="group B: one run per training seed, same seed order as --a"
    )
    p.add_argument(
        "--label-a", default=None, help="name of group/run A in tables (default: its data regime or policy)"
    )
    p.add_argument("--label-b", default=None, help="name of group/run B in tables")
    p.add_argument(
        "--axes", default=None, metavar="A_AXIS:B_AXIS",
        help="compare axis A against axis B, paired episode by episode (same task, level, episode and seed): within "
        "one run (compare RUN --axes pick_y+distractor:pick_y) or A of RUN_A against B of RUN_B",
    )  # fmt: skip
    p.add_argument(
        "--margin", type=float, default=0.10,
        help="equivalence margin (default 0.10): groups: TOST on the OOD mean success; --axes: paired TOST per level",
    )  # fmt: skip
    p.add_argument(
        "--test",
        choices=["auto", "mcnemar", "boschloo", "barnard"],
        default="auto",
        help="auto: exact McNemar when the runs are paired episode by episode (same seeds and plan), else "
        "Boschloo (default auto)",
    )
    p.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    p.add_argument("--alpha", type=float, default=0.05, help="significance level after Holm (default 0.05)")
    p.add_argument(
        "--allow-protocol-mismatch",
        action="store_true",
        help="compare runs whose protocol fingerprints differ in a field that changes outcomes (horizon, assets, "
        "simulator versions, cameras, render backend, conventions of one policy family); the output lists them",
    )
    p.add_argument(
        "--out", default=None, help="output folder (default: RUN_A/compare; --axes A:B: RUN_A/compare_A_vs_B)"
    )


def _add_reference(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser(
        "reference",
        help="black-box regime: pick T0 from reference policies' runs, test the level ordering on held-out episodes",
        description="Black-box reference level (paper appendix B): each RUN_DIR is one reference policy evaluated on "
        "the (task, level) configurations of one axis. T0 = the configuration with the highest mean success over "
        "the policies, chosen on even-numbered episodes; the ordering of the levels around T0 is then tested "
        "(isotonic LRT and Cochran-Armitage) on the held-out odd-numbered episodes.",
    )
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="one run directory per reference policy")
    p.add_argument(
        "--axis", default=None, help="axis whose levels are the configurations (default: the only shared one)"
    )
    p.add_argument(
        "--task", default=None, help="restrict the configurations to one task (default: every shared task)"
    )
    p.add_argument(
        "--level", type=int, default=None,
        help="choose T0 only among the configurations at this level, e.g. 0: the canonical configurations "
        "themselves (RoboCasa: --task Task@5x5 runs its canonical kitchens); default: every (task, level)",
    )  # fmt: skip
    p.add_argument("--out", default=None, help="folder for reference.json/.md (default: FIRST_RUN/reference)")


def _add_serve(sp: argparse._SubParsersAction) -> None:
    p = sp.add_parser("serve", help="serve any policy over openpi's websocket protocol")
    p.add_argument(
        "--policy", required=True, help="policy spec to serve, e.g. lerobot:HUB_ID or standin:oracle"
    )
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument("--api-key", default=None, help="require 'Authorization: Api-Key KEY' from clients")
    p.add_argument(
        "--trust-remote-code", action="store_true", help="allow checkpoints that ship their own code"
    )


def _add_simple(sp: argparse._SubParsersAction, name: str, help_: str) -> argparse.ArgumentParser:
    p = sp.add_parser(name, help=help_)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    return p


PASSTHROUGH = {"blockenv", "demos", "mimicgen", "train", "real"}  # subcommands that parse their own arguments


def _add_passthrough(sp: argparse._SubParsersAction, name: str, help_: str) -> None:
    sp.add_parser(name, help=help_, add_help=False)


def build_parser() -> argparse.ArgumentParser:
    parser = IndgenParser(
        prog="indgen",
        description="Measure inductive generalization of robot policies: move a task one atomic step at a "
        "time along one axis, run the policy, report success per level and the break level k*.",
    )
    parser.add_argument("--version", action="version", version=f"indgen-vla {__version__}")
    sp = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=IndgenParser)
    _add_evaluate(sp)
    _add_certify(sp)
    _add_preview(sp)
    _add_report(sp)
    _add_merge(sp)
    _add_compare(sp)
    _add_reference(sp)
    _add_serve(sp)
    _add_simple(sp, "scenes", "list registered scenes and their tasks")
    _add_simple(sp, "axes", "list registered axes with step, level range and description")
    _add_simple(sp, "policies", "list policy spec families and stand-ins")
    p = sp.add_parser(
        "setup", help="create a scene family's own simulator environment (robocasa: a pinned venv)"
    )
    p.add_argument("family", choices=["robocasa"], help="the scene family whose environment to create")
    p.add_argument("--venv", default=None, help="where to create it (default: $INDGEN_ROBOCASA_VENV or "
                   "~/.cache/indgen/robocasa-venv)")  # fmt: skip
    p.add_argument("--force", action="store_true", help="recreate it even when it is complete")
    _add_passthrough(sp, "blockenv", "the toy BlockEnv benchmark: sample | train | eval | reproduce | ablate")
    _add_passthrough(sp, "demos", "record demonstrations (T0, or levels of one axis) as a LeRobotDataset")
    _add_passthrough(
        sp, "mimicgen", "MimicGen-style augmentation of demonstrations (each at its source level)"
    )
    _add_passthrough(sp, "train", "train a small LeRobot policy (ACT/Diffusion) on one or more datasets")
    _add_passthrough(sp, "real", "real-robot protocol with an operator: plan | record | status")
    return parser


def _resolve(command: str):
    importlib.import_module("indgen_vla.engine")  # registers the scene-side stand-ins (standin:oracle)
    module, _, func = HANDLERS[command].partition(":")
    return getattr(importlib.import_module(module), func)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``indgen`` console script. Exit codes (README "Exit codes"): 0 success, 1 an
    unexpected crash, 2 bad input (``IndgenError``), 3 ``evaluate`` finished with ``error`` episodes, 4 it
    stopped early because the policy server stayed unreachable, 130 Ctrl-C, 143 SIGTERM."""
    try:
        return _main(argv)
    finally:
        if argv is None:  # the console script: the interpreter exits next
            # its shutdown would garbage-collect every object torch/lerobot/transformers made, several times
            # (seconds after a LeRobot policy, docs/benchmarks.md "Start-up"). Frozen, they are left to the OS;
            # atexit handlers still run, and every file of the run is closed by now.
            gc.freeze()


PIPED_COLUMNS = 240  # the table width when stdout is not a terminal and $COLUMNS is unset


def _main(argv: Sequence[str] | None) -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    # piped or logged: rich would cut tables (task names, readiness notes) to 80 columns
    if not sys.stdout.isatty():
        os.environ.setdefault("COLUMNS", str(PIPED_COLUMNS))
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if args.command in PASSTHROUGH:
        args.rest = extra
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    if not args.command:
        parser.print_help()
        return 2
    try:
        with sigterm_raises():
            return int(_resolve(args.command)(args) or 0)
    except IndgenError as e:
        print(f"error: {e}", file=sys.stderr)
        return e.exit_code
    except Terminated:
        print(interrupted_message(args).replace("interrupted:", "terminated (SIGTERM):", 1), file=sys.stderr)
        return EXIT_SIGTERM
    except KeyboardInterrupt:
        print(interrupted_message(args), file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `indgen axes | head`: the reader left; not an error of ours
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
