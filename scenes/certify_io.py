"""Where certificates live, how ``evaluate`` finds them, the SUMMARY table and the ``indgen certify`` CLI.

Built-in scenes: ``scenes/certification/<scene>/<task>/<axis>/certify.json`` (committed). LIBERO suites and
RoboCasa365: ``$INDGEN_CACHE/certification/<hash of the asset tree path>/<scene>/<task>/<axis>/certify.json``
(``$INDGEN_CACHE`` defaults to ``~/.cache/indgen``), written by ``indgen certify`` on the user's machine; each
records its tree's ``asset_stamp`` (every file's path, size and mtime), and one whose tree has changed since (or
made before stamps were recorded) is never used: ``find_certification`` ignores it and ``certify`` makes it again.
``$INDGEN_CERT_DIR`` replaces either root. An axis certified at non-default steps gets its own folder
``<axis>@<component>=<step>,...``.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from indgen_vla.core.errors import RunDirError
from scenes.certify_progress import CertifyDisplay
from scenes.certify_run import (
    asset_stamp,
    certified_levels,
    certify,
    episodes_needed,
    infeasible_levels,
    level_status,
    load_certification,
    same_assets,
)
from scenes.oracle import oracle_scripts
from scenes.registry import get_scene, registered_scenes


def certification_root(scene: str | None = None) -> Path:
    """$INDGEN_CERT_DIR, else the committed certificates (``indgen_vla.core.resources.certification_dir``) for the built-in
    scenes, else a cache folder per asset tree."""
    env = os.environ.get("INDGEN_CERT_DIR")
    if env:
        return Path(env)
    if scene is None or get_scene(scene).committed_certificates:
        from indgen_vla.core.resources import certification_dir

        return certification_dir()
    assets = get_scene(scene).asset_tree()
    tag = hashlib.sha1(str(assets.resolve() if assets else "none").encode()).hexdigest()[:12]
    return Path(os.environ.get("INDGEN_CACHE", "~/.cache/indgen")).expanduser() / "certification" / tag


def axis_dirname(
    axis: str, step: float | None = None, preset: str | None = None, scene: str | None = None,
    task: str | None = None,
) -> str:  # fmt: skip
    """``axis`` at the (family's, task's) default steps, else ``axis@comp=step,...`` so other steps never overwrite
    it."""
    import scenes
    from scenes.axes import successor_steps

    steps = successor_steps(scenes.successor_for(axis, step, preset, scene, task))
    if steps == successor_steps(scenes.successor_for(axis, scene=scene, task=task)):
        return axis
    return axis + "@" + ",".join(f"{k}={v:g}" for k, v in steps.items())


def cert_path(
    scene: str, task: str | None, axis: str, step: float | None = None, preset: str | None = None,
    root: str | Path | None = None,
) -> Path:  # fmt: skip
    """The certify.json of (scene, task, axis, steps)."""
    task = get_scene(scene).resolve_task(task)
    base = Path(root) if root is not None else certification_root(scene)
    return base / scene / task / axis_dirname(axis, step, preset, scene, task) / "certify.json"


def find_certification(
    scene: str, task: str | None, axis: str, step: float | None = None, *, preset: str | None = None,
    root: str | Path | None = None,
) -> dict | None:  # fmt: skip
    """The certificate of (scene, task, axis) made at these component steps, or None if there is none."""
    import json

    import scenes
    from scenes.axes import successor_steps

    want = successor_steps(
        scenes.successor_for(axis, step, preset, scene, get_scene(scene).resolve_task(task))
    )

    def same_steps(cert: dict) -> bool:
        have = cert.get("steps") or {axis: cert.get("step")}
        return json.dumps(want, sort_keys=True) == json.dumps(
            {k: float(v) for k, v in have.items()}, sort_keys=True
        )

    path = cert_path(scene, task, axis, step, preset, root)
    if path.is_file():
        cert = load_certification(path)
        if same_steps(cert) and same_assets(cert, asset_stamp(scene)):  # a changed tree: certify again
            return cert
    if root is None and not os.environ.get("INDGEN_CERT_DIR"):
        from indgen_vla.core.resources import certification_dir
        from scenes.certify_shipped import shipped_certification

        cert = shipped_certification(scene, cert_path(scene, task, axis, step, preset, certification_dir()))
        if cert is not None and same_steps(cert):
            return cert
    return None


def print_table(cert: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    rule = cert.get("rule", {})
    table = Table(
        title=f"certification: {cert['scene']}/{cert['task']}, axis {cert['axis']} (step {cert['step']:g} {cert['unit']})",
        caption=f"privileged oracle; certified when the one-sided {rule.get('confidence', 0.95):.0%} Clopper-Pearson "
        f"lower bound >= {cert['threshold']:.0%} (at most {cert.get('episodes')} episodes per level)",
    )
    for col in ("level", "param", "successes/n", "rate", "CP lower", "status"):
        table.add_column(col, justify="right")
    for r in cert["levels"]:
        st = level_status(r)
        table.add_row(
            str(r["level"]), f"{r['param']:g}", f"{r['successes']}/{r['n']}", f"{r['rate']:.0%}",
            f"{r.get('lower_bound', float('nan')):.3f}", st if st != "failed" else "[red]failed[/red]",
        )  # fmt: skip
    Console().print(table)


def certify_main(args) -> int:
    """``indgen certify``: write certify.json per task (resuming what is there); exit 1 if a level failed."""
    tasks = get_scene(args.scene).select_tasks(args.task, (args.axis,))
    preset = getattr(args, "axes_preset", None)
    failed = False
    for task in tasks:
        if args.out is None:
            path = cert_path(args.scene, task, args.axis, args.step, preset)
        else:
            path = Path(args.out) / (task if len(tasks) > 1 else "") / "certify.json"
        if len(tasks) > 1 and not oracle_scripts(args.scene, task):
            print(
                f"{args.scene}/{task}/{args.axis}: uncertified (standin:oracle has no script for this task)"
            )
            continue
        try:
            with CertifyDisplay(args.scene, get_scene(args.scene).resolve_task(task), args.axis) as display:
                cert = certify(
                    args.scene, args.axis, task=task, levels=args.levels, step=args.step, episodes=args.episodes,
                    seed=args.seed, max_steps=args.max_steps, workers=args.workers or 1,
                    threshold=getattr(args, "threshold", None) or 0.95, preset=preset, out=path,
                    log=display.log, watch=display,
                )  # fmt: skip
        except OSError as e:
            raise RunDirError(f"cannot write {path}: {e.strerror}; pick another --out") from None
        print_table(cert)
        print(f"certificate: {path}")
        bad = infeasible_levels(cert)
        if bad:
            print(f"{cert['scene']}/{cert['task']}/{cert['axis']}: levels {bad} failed (the oracle failed; the "
                  f"bound cannot reach {cert['threshold']:.0%})")  # fmt: skip
            failed = True
        short = sorted({int(r["level"]) for r in cert["levels"]} - set(bad) - set(certified_levels(cert)))
        if short:
            print(f"{cert['scene']}/{cert['task']}/{cert['axis']}: levels {short} lack evidence "
                  f"({cert['episodes']} episodes cannot certify; the rule needs {_needed(cert)})")  # fmt: skip
    return 1 if failed else 0


def _needed(cert: dict) -> int:
    rule = cert.get("rule", {})
    return episodes_needed(cert["threshold"], rule.get("confidence", 0.95))


def default_jobs(scene_names: list[str] | None = None) -> list[tuple[str, str, str]]:
    """Every (scene, task, axis) of the scenes with committed certificates (the built-ins) in priority order:
    each task's first axis, then the rest and the scene's ``certified_compositions``."""
    defs = [
        s
        for s in registered_scenes()
        if s.committed_certificates and (scene_names is None or s.name in scene_names)
    ]
    first = [(s.name, t, s.axes[0]) for s in defs for t in s.tasks]
    rest = [(s.name, t, a) for s in defs for a in (*s.axes[1:], *s.certified_compositions) for t in s.tasks]
    return first + rest


def certify_all(
    out_dir: str | Path | None = None, episodes: int | None = None, workers: int = 1, seed: int = 0,
    scene_names: list[str] | None = None, log=print,
) -> list[dict]:  # fmt: skip
    """Certify (or resume) every default level of every (scene, task, axis) in priority order, rewriting
    SUMMARY.md after each; every certify.json is replaced atomically after each level."""
    root = Path(out_dir) if out_dir is not None else certification_root()
    certs = []
    for scene, task, axis in default_jobs(scene_names):
        if not oracle_scripts(scene, task):
            if log:
                log(f"{scene}/{task}/{axis}: uncertified (standin:oracle has no script for this task)")
            continue
        try:
            cert = certify(scene, axis, task=task, episodes=episodes, seed=seed, workers=workers,
                           out=cert_path(scene, task, axis, root=root), log=log)  # fmt: skip
        except Exception as e:  # a batch over hundreds of levels logs one broken triple and goes on
            log(f"{scene}/{task}/{axis}: FAILED, skipped ({type(e).__name__}: {e})")
            continue
        certs.append(cert)
        write_summary(root)
    return certs


def write_summary(out_dir: str | Path) -> Path:
    """Collect every ``<scene>/<task>/<axis>/certify.json`` under ``out_dir`` into SUMMARY.md."""
    out_dir = Path(out_dir)
    jobs = default_jobs()
    lines = [
        "# Certification summary (generated by scenes.certify_io.write_summary; do not edit)",
        "",
        "A level is certified when the one-sided 95 % Clopper-Pearson lower bound of the oracle's success rate",
        "is >= the threshold (see README.md). `s/n` per level; `!` failed, `?` not enough evidence yet.",
        "",
    ]
    have = {p.parent.relative_to(out_dir).parts for p in out_dir.glob("*/*/*/certify.json")}
    complete = 0
    rows = [
        "| scene | task | axis | step | levels (s/n) | certified | not certified |",
        "|---|---|---|---|---|---|---|",
    ]
    for path in sorted(out_dir.glob("*/*/*/certify.json")):
        c = load_certification(path)
        cells = " ".join(
            f"{r['level']}: {r['successes']}/{r['n']}"
            + {"failed": "!", "insufficient": "?"}.get(level_status(r), "")
            for r in c["levels"]
        )
        ok = certified_levels(c)
        levels = {int(r["level"]) for r in c["levels"]}
        try:
            import scenes

            want = set(scenes.get_axis(c["axis"]).default_levels())
        except Exception:  # an axis this version no longer knows: report what is there
            want = levels
        missing = sorted(want - set(ok))
        complete += not missing
        rows.append(
            f"| {c['scene']} | {c.get('task', '?')} | {path.parent.name} | {c.get('step', 0):g} {c.get('unit', '')} "
            f"| {cells} | {', '.join(map(str, ok)) or 'none'} | {', '.join(map(str, missing)) or '-'} |"
        )
    todo = [j for j in jobs if (j[0], j[1], j[2]) not in have]
    lines.append(
        f"{complete} of {len(jobs)} default (scene, task, axis) triples have every default level certified; "
        f"{len(todo)} have no certificate yet."
    )
    lines += ["", *rows, ""]
    target = out_dir / "SUMMARY.md"
    tmp = target.with_name(f".SUMMARY.md.{os.getpid()}.tmp")
    tmp.write_text("\n".join(lines))
    os.replace(tmp, target)
    return target


__all__ = [
    "certification_root", "axis_dirname", "cert_path", "find_certification",
    "print_table", "certify_main", "default_jobs", "certify_all", "write_summary", "RunDirError",
]  # fmt: skip
