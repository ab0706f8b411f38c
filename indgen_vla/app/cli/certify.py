"""``indgen certify``: its parser; the handler certifies each task (``indgen_vla.app.certify.run.certify``) with the
live display and prints each certificate's table and verdicts."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_level_options, add_scene_options


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The certify subcommand: scene, task, axis, levels, the rule's episodes and threshold, seed, workers, folder."""
    p = sp.add_parser("certify", help="certify every level of an axis with the privileged oracle")
    p.add_argument(
        "--scene", default=None, help="scene to certify (see 'indgen scenes'); with --audit, a filter"
    )
    p.add_argument("--task", default=None, help="task of the scene, or 'all' (default: the first task)")
    p.add_argument("--axis", default=None, help="axis or composition, e.g. pick_y or pick_y+distractor")
    add_level_options(p)
    p.add_argument(
        "--episodes", type=int, default=None, help="most episodes per level (default: the 59 the rule needs)"
    )
    p.add_argument(
        "--threshold", type=float, default=None, help="oracle success rate to certify (default 0.95)"
    )
    p.add_argument(
        "--seed", type=int, default=1,
        help="first seed block an attempt may draw (default 1; block 0 is burnt, and each attempt takes a block the "
        "level never used: scenes/certification/README.md)",
    )  # fmt: skip
    p.add_argument(
        "--audit", type=int, default=None, metavar="N",
        help="re-run N shipped certified levels drawn at random (--seed draws them) on fresh held-out seeds, "
        "--episodes each (default 20), and say whether each still holds; writes --out/audit.json if --out",
    )  # fmt: skip
    p.add_argument(
        "--evaluation-states", action="store_true",
        help="with --run DIR: play the oracle on the exact initial states of that evaluate run's episodes "
        "(--episodes n: episodes 0..n-1) and write DIR/oracle_states.json; 'indgen report DIR' then splits the "
        "policy's failures by whether the oracle solved the state",
    )  # fmt: skip
    p.add_argument("--run", default=None, help="an evaluate run directory (--evaluation-states)")
    p.add_argument(
        "--held-out", action="store_true",
        help="also re-run, on a fresh seed block, the levels certified only in-sample (tuned)",
    )  # fmt: skip
    p.add_argument("--max-steps", type=int, default=None, help="override the scene's episode length")
    p.add_argument("--workers", type=int, default=1, help="processes, one level each (physics only)")
    add_scene_options(p)
    p.add_argument(
        "--out", default=None, help="folder for certify.json (default: where evaluate looks; resumes there)"
    )


def main(args: argparse.Namespace) -> int:
    """Write certify.json per task (resuming what is there); exit 1 if a level failed."""
    from indgen_vla.core.errors import ConfigError
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from indgen_vla.core.runs.records import RunDir
    from scenes.family import get_scene

    if args.audit is not None:
        return _audit(args)
    if args.evaluation_states:
        if not args.run:
            raise ConfigError(
                "--evaluation-states needs --run DIR, the evaluate run whose initial states to play"
            )
        from indgen_vla.app.certify.states import certify_evaluation_states

        family = get_scene(RunDir(args.run).manifest["scene"])  # the run's own scene
        out = certify_evaluation_states(args.run, family, episodes=args.episodes)
        solved = [s["solved"] for s in out["states"]]
        print(f"the oracle solved {sum(s is True for s in solved)} of {sum(s is not None for s in solved)} "
              f"evaluated states of {args.run}; run 'indgen report {args.run}' to split the policy's failures")  # fmt: skip
        return 0
    if not args.scene or not args.axis:
        raise ConfigError(
            "indgen certify needs --scene and --axis (or --audit N to check shipped certificates)"
        )
    axis = AxisRef.parse(args.axis)  # a malformed name: one line, before any scene lookup
    options = {"split": args.split, "obj_registries": args.obj_registries}  # a bad value: one line, here
    # one choice for the certificates' folder and every level: the family configured once, handed on
    return _certify_tasks(args, axis, get_scene(args.scene, options))


def _certify_tasks(args: argparse.Namespace, axis, sc) -> int:
    """Each task of ``args`` in turn on ``sc``, the scene configured."""
    from pathlib import Path

    from indgen_vla.app.certify.display import CertifyDisplay, print_table
    from indgen_vla.app.certify.run import certify
    from indgen_vla.core.errors import RunDirError
    from scenes.certificates import cert_path, certified_levels, infeasible_levels
    from scenes.oracles import oracle_scripts

    tasks = sc.select_tasks(args.task, (axis,))
    preset = args.axes_preset
    failed = False
    for task in tasks:
        if args.out is None:
            path = cert_path(sc, task, axis, args.step, preset)
        else:
            path = Path(args.out) / (task if len(tasks) > 1 else "") / "certify.json"
        if len(tasks) > 1 and not oracle_scripts(sc, task):
            print(
                f"{args.scene}/{task}/{args.axis}: uncertified (standin:oracle has no script for this task)"
            )
            continue
        try:
            with CertifyDisplay(args.scene, sc.resolve_task(task), args.axis) as display:
                cert = certify(
                    sc, axis, task=task, levels=args.levels, step=args.step, episodes=args.episodes,
                    seed=args.seed, max_steps=args.max_steps, workers=args.workers or 1,
                    threshold=args.threshold or 0.95, preset=preset, out=path,
                    log=display.log, watch=display, retest=args.held_out,
                )  # fmt: skip
        except OSError as e:
            raise RunDirError(f"cannot write {path}: {e.strerror}; pick another --out") from None
        print_table(cert, sc)
        print(f"certificate: {path}")
        bad = infeasible_levels(cert)
        if bad:
            v = (cert.get("oracle") or {}).get("version", "?")
            print(f"{cert['scene']}/{cert['task']}/{cert['axis']}: levels {bad} failed (oracle v{v} failed; the "
                  f"bound cannot reach {cert['threshold']:.0%})")  # fmt: skip
            failed = True
        short = sorted({int(r["level"]) for r in cert["levels"]} - set(bad) - set(certified_levels(cert)))
        if short:
            print(f"{cert['scene']}/{cert['task']}/{cert['axis']}: levels {short} lack evidence "
                  f"({cert['episodes']} episodes cannot certify; the rule needs {_needed(cert)})")  # fmt: skip
    return 1 if failed else 0


def _needed(cert: dict) -> int:
    from scenes.certificates import episodes_needed

    rule = cert.get("rule", {})
    return episodes_needed(cert["threshold"], rule.get("confidence", 0.95))


def _audit(args: argparse.Namespace) -> int:
    """``--audit N``: exit 1 when a drawn level no longer holds."""
    from pathlib import Path

    from indgen_vla.app.certify.audit import audit

    scenes = args.scene.split(",") if args.scene else None
    out = Path(args.out) / "audit.json" if args.out else None
    result = audit(args.audit, scenes=scenes, episodes=args.episodes or 20, seed=args.seed,
                   workers=args.workers or 1, out=out)  # fmt: skip
    rows = result["levels"]
    broken = [r for r in rows if not r["holds"]]
    print(f"audit: {len(rows) - len(broken)} of {len(rows)} levels hold ({result['episodes']} held-out episodes "
          f"each; a level is broken when the one-sided binomial test of rate >= 0.95 rejects at 5 %)"
          + (f"; audit.json: {out}" if out else ""))  # fmt: skip
    return 1 if broken else 0
