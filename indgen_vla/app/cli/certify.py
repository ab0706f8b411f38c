"""``indgen certify``: its parser, made from ``CertifyConfig``'s fields; the handler builds the config, resolves the
scene once and certifies each task (``indgen_vla.app.certify.certify_levels.certify``) with the live display,
printing each certificate's table and verdicts."""

from __future__ import annotations

import argparse

from indgen_vla.app.certify.certify_config import COMMAND, FLAG_ORDER, CertifyConfig
from indgen_vla.app.config_fields import add_flags, from_args


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The certify subcommand: scene, task, axis, levels, the rule's episodes and threshold, seed, workers, folder."""
    p = sp.add_parser("certify", help="certify every level of an axis with the privileged oracle")
    add_flags(p, CertifyConfig, FLAG_ORDER)


def main(args: argparse.Namespace) -> int:
    """Write certify.json per task (resuming what is there); exit 1 if a level failed."""
    from scenes.family import get_scene  # lazy: start-up (--help imports no scene)

    config = from_args(CertifyConfig, args, command=COMMAND)
    if config.mode == "audit":
        return _audit(config)
    if config.mode == "evaluation_states":
        return _evaluation_states(config)
    # one choice of the family's options for the certificates' folder and every level (a bad value: one line)
    return _certify_tasks(config, get_scene(config.plan.scene, config.plan.scene_options()))


def _evaluation_states(config: CertifyConfig) -> int:
    """``--evaluation-states --run DIR``: the oracle on that run's initial states."""
    from indgen_vla.app.certify.states import certify_evaluation_states  # lazy: start-up
    from indgen_vla.core.runs.records import RunDir  # lazy: start-up
    from scenes.family import get_scene  # lazy: start-up

    run = config.check.run_dir
    family = get_scene(RunDir(run).manifest["scene"])  # the run's own scene
    out = certify_evaluation_states(run, family, episodes=config.rule.episodes)
    solved = [s["solved"] for s in out["states"]]
    print(f"the oracle solved {sum(s is True for s in solved)} of {sum(s is not None for s in solved)} "
          f"evaluated states of {run}; run 'indgen report {run}' to split the policy's failures")  # fmt: skip
    return 0


def _certify_tasks(config: CertifyConfig, scene) -> int:
    """Each task of ``config`` in turn, on the scene resolved once."""
    import dataclasses  # lazy: start-up (the handler's imports; --help imports no scene)
    from pathlib import Path

    from indgen_vla.app.certify.certify_levels import certify  # lazy: start-up
    from indgen_vla.app.certify.display import CertifyDisplay, print_table  # lazy: start-up
    from indgen_vla.core.errors import RunDirError  # lazy: start-up
    from scenes.certificates import cert_path, certified_levels, infeasible_levels  # lazy: start-up
    from scenes.oracles import oracle_scripts  # lazy: start-up

    plan, axis = config.plan, config.plan.axis
    tasks = scene.select_tasks(plan.task, (axis,))
    failed = False
    for task in tasks:
        if config.run.out is None:
            path = cert_path(scene, task, axis, plan.step, plan.axes_preset)
        else:
            path = Path(config.run.out) / (task if len(tasks) > 1 else "") / "certify.json"
        if len(tasks) > 1 and not oracle_scripts(scene, task):
            print(f"{scene.name}/{task}/{axis}: uncertified (standin:oracle has no script for this task)")
            continue
        one = dataclasses.replace(config, plan=dataclasses.replace(plan, task=task))
        try:
            with CertifyDisplay(scene.name, scene.resolve_task(task), str(axis)) as display:
                cert = certify(scene, one, path, log=display.log, watch=display)
        except OSError as e:
            raise RunDirError(f"cannot write {path}: {e.strerror}; pick another --out") from None
        print_table(cert, scene)
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
    from scenes.certificates import episodes_needed  # lazy: start-up

    rule = cert.get("rule", {})
    return episodes_needed(cert["threshold"], rule.get("confidence", 0.95))


def _audit(config: CertifyConfig) -> int:
    """``--audit N``: exit 1 when a drawn level no longer holds."""
    from pathlib import Path  # lazy: start-up (the handler's imports; --help imports no scene)

    from indgen_vla.app.certify.audit import audit  # lazy: start-up
    from scenes.family import get_scene, registered_scenes  # lazy: start-up

    names = config.audit_scenes
    scenes = [get_scene(n) for n in names] if names else registered_scenes()  # an unknown name: one line
    out = Path(config.run.out) / "audit.json" if config.run.out else None
    result = audit(config, scenes, out=out)
    rows = result["levels"]
    broken = [r for r in rows if not r["holds"]]
    print(f"audit: {len(rows) - len(broken)} of {len(rows)} levels hold ({result['episodes']} held-out episodes "
          f"each; a level is broken when the one-sided binomial test of rate >= 0.95 rejects at 5 %)"
          + (f"; audit.json: {out}" if out else ""))  # fmt: skip
    return 1 if broken else 0
