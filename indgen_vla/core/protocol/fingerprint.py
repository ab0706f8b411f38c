"""Protocol fingerprints: what fixed a run's outcomes, so two runs are paired or pooled only when comparable.

``evaluate`` writes one into the manifest when its first episode is about to run (``build_fingerprint``): the scene
family, the simulator packages (and a worker environment's), the asset tree's identity, the horizon and settling steps,
where initial states come from, the cameras and their size, the render backend actually used, the policy's resolved
conventions, the certificate behind each level and the episode plan's hash. ``compare`` and ``report`` read them back
(``check_comparable``): a difference in a field that changes outcomes refuses pairing or pooling in one line naming
the field (``--allow-protocol-mismatch`` overrides, and the output then names the difference); the certificates and the
plan hash are shown but never refuse, and the policy's conventions refuse only between runs of the same policy family
(comparing two families is the point of a comparison; a flip that differs between two checkpoints of one family is not).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

from indgen_vla.core.errors import ConfigError

SIMULATOR_PACKAGES = ("robosuite", "mujoco", "hf-libero", "numpy")
OUTCOME_FIELDS = ("scene", "family", "simulator", "assets", "horizon", "settle_steps", "initial_states", "cameras",
                  "image_size", "render_backend")  # fmt: skip
POLICY_FIELD = "policy"
# "numerics": the CPU and builds floating point depends on (``numeric_builds``): outcomes of a neural policy run in
# this process are bit-equal only where they match (docs/run-directory.md "What is bit-equal across machines")
INFO_FIELDS = ("certificates", "plan_sha256", "numerics")
NUMERICS = "numerics"
NO_RENDER = "none (the policy reads no camera)"


class ProtocolMismatchError(ConfigError):
    """Two runs made under different protocols were about to be paired or pooled."""


def build_fingerprint(
    resolved: Mapping[str, Any],
    versions: Mapping[str, str],
    *,
    max_steps: int | None,
    warmup_steps: int,
    cameras: Sequence[str],
    image_size: tuple[int, int],
    render_backend: str,
    policy: Mapping[str, Any],
) -> dict[str, Any]:
    """The fingerprint of a run from its manifest's ``resolved`` plan and what the engine resolved at start-up.

    Args:
        resolved: ``EvalPlan.record()`` (environment with the scene's protocol facts, cells, plan hash).
        versions: installed package versions (``engine.run.package_versions``).
        max_steps: ``--max-steps``, None for the scene's own horizon.
        warmup_steps: ``--warmup-steps`` (no-op steps the engine adds after the scene's own settling).
        cameras: the cameras rendered for the policy (empty: nothing is rendered).
        image_size: the rendered (H, W).
        render_backend: the GL vendor/renderer string (ignored when no camera is read).
        policy: the policy's family and resolved conventions (``policy_conventions``).
    """
    env = resolved.get("environment", {})
    facts = env.get("protocol", {})
    simulator = {k: versions[k] for k in SIMULATOR_PACKAGES if k in versions}
    simulator.update({f"worker:{k}": v for k, v in (env.get("environment") or {}).items()})
    return {
        "scene": env.get("scene"),
        "family": env.get("family"),
        "simulator": simulator,
        "assets": facts.get("assets"),
        "horizon": max_steps or facts.get("max_steps"),
        "settle_steps": int(facts.get("settle_steps", 0)) + int(warmup_steps),
        "initial_states": facts.get("initial_states"),
        "cameras": list(cameras),
        "image_size": list(image_size) if cameras else None,
        "render_backend": render_backend if cameras else NO_RENDER,
        POLICY_FIELD: dict(policy),
        "certificates": {
            f"{c['task']}/{c['axis']}/{c['level']}": c["certificate"] for c in resolved.get("cells", [])
        },
        "plan_sha256": resolved.get("jobs_sha256"),
    }


def _cpuinfo() -> tuple[str, set[str] | None]:
    """This machine's CPU model and flags from /proc/cpuinfo (flags None where it cannot be read)."""
    try:
        with open("/proc/cpuinfo") as f:
            lines = f.read().splitlines()
    except OSError:
        return "", None
    info = {
        k.strip(): v.strip() for k, _, v in (ln.partition(":") for ln in lines if ":" in ln)
    }  # every core alike
    return info.get("model name", ""), set(info.get("flags", "").split())


def cpu_isa(flags: set[str] | None = None) -> str:
    """The instruction set torch's CPU kernels dispatch to on this machine, as ``torch.backends.cpu.
    get_cpu_capability()`` names it (lower case), read from the CPU's flags so that recording it imports nothing:
    ATen's rule (``ATEN_CPU_CAPABILITY`` overrides; AVX512 needs avx512vl, bw, dq and fma; AVX2 avx2 and fma)."""
    override = os.environ.get("ATEN_CPU_CAPABILITY", "").strip().lower()
    if override:
        return override
    if flags is None:
        flags = _cpuinfo()[1]
        if flags is None:
            return "unknown"
    if {"avx512vl", "avx512bw", "avx512dq", "fma"} <= flags:
        return "avx512"
    if {"avx2", "fma"} <= flags:
        return "avx2"
    return "default"


def numeric_builds(versions: Mapping[str, str]) -> dict[str, Any]:
    """The machine and builds a run's floating point depends on: the CPU, the instruction set torch's kernels
    dispatch to there (AVX2, AVX512: a network's last bits differ between them) and torch's build (``versions``:
    the run's package versions, ``engine.run.package_versions``)."""
    import platform

    model, flags = _cpuinfo()
    out: dict[str, Any] = {
        "machine": platform.machine(),
        "cpu": model or platform.processor(),
        "cpu_isa": cpu_isa(flags),  # the override first; unreadable flags: "unknown"
    }
    if "torch" in versions:
        out["torch"] = versions["torch"]
    return out


def numerics_warning(was: Mapping[str, Any] | None, now: Mapping[str, Any] | None, what: str) -> str | None:
    """One line when two runs' (or a run and its resume's) ``numerics`` differ where a neural policy's outcomes can:
    the instruction set, torch's build or the machine (another CPU model alone is no warning); None otherwise."""
    if not was or not now:
        return None
    keys = [k for k in ("cpu_isa", "torch", "machine", "cpu") if was.get(k) != now.get(k)]
    if not set(keys) - {"cpu"}:
        return None
    diff = "; ".join(f"{k} {was.get(k)} vs {now.get(k)}" for k in keys)
    return (
        f"{what} on other numerics ({diff}): a neural policy's episodes may differ in their last bits and an "
        "adaptive rule's decisions with them (docs/run-directory.md, 'What is bit-equal across machines')"
    )


def workers_warning(was: Any, now: Any, batched: bool) -> str | None:
    """One line when a run is resumed under another ``--workers`` (ints; ``auto`` is not compared) with a batched
    policy: its forward is padded to the worker count, and a neural one can round differently at another batch size,
    so the episodes run now may not be those an uninterrupted run makes; None otherwise."""
    if not batched or not isinstance(was, int) or not isinstance(now, int) or was == now:
        return None
    return (
        f"resumed with --workers {now}, the run began with --workers {was}: the policy's batches are padded to the "
        "worker count, so a neural policy's episodes may differ in their last bits from an uninterrupted run's "
        f"(docs/run-directory.md); resume with --workers {was} for bit-equal outcomes"
    )


def policy_conventions(spec, policy) -> dict[str, Any]:
    """A policy's resolved conventions: its spec's serving facts and the frozen transforms it applies (crop,
    resize, flip, gripper map), as their reprs, and on a scene family with its own robot the layout it used
    (``layout``: which upstream state/action order, e.g. lerobot's base-first RoboCasa action); the earlier
    steps it sees (``history_steps``), where it sees any."""
    conv = getattr(policy, "conventions", None) or getattr(
        getattr(policy, "config", None), "conventions", None
    )
    out = {
        "family": spec.family,
        "chunk_size": spec.chunk_size,
        "replan_steps": spec.replan_steps,
        "flip_180": spec.flip_180,
        "conventions": repr(conv) if conv is not None else None,
    }
    if getattr(spec, "history_steps", 0):  # absent without history: those fingerprints are unchanged
        out["history_steps"] = spec.history_steps
    layout = getattr(policy, "layout", None)  # a ``layouts.Layout`` on a scene family with its own robot
    if layout is not None:  # absent on the tabletop families, so their fingerprints are unchanged
        out["layout"] = layout.describe()
    return out


# scene families whose class moved module without changing (scenes/ became one folder per family): a run recorded
# under the old path is the same family, so it resumes and compares as before
MOVED_FAMILIES = {"scenes.catalog.": "scenes.tabletop."}


def _field(fp: Mapping[str, Any], field: str) -> Any:
    """``fp[field]``, a moved family's class path read as its current one."""
    v = fp.get(field)
    if field == "family" and isinstance(v, str):
        for old, new in MOVED_FAMILIES.items():
            if v.startswith(old):
                return new + v[len(old) :]
    return v


def digest(fp: Mapping[str, Any]) -> str:
    """A short hash of the fields that change outcomes (equal digests: comparable runs)."""
    keep = {k: _field(fp, k) for k in (*OUTCOME_FIELDS, POLICY_FIELD)}
    return hashlib.sha256(json.dumps(keep, sort_keys=True, default=str).encode()).hexdigest()[:12]


def differences(a: Mapping[str, Any], b: Mapping[str, Any]) -> list[tuple[str, Any, Any, bool]]:
    """(field, value in a, value in b, changes outcomes) for every field that differs; ``policy.<key>`` for the
    policy's conventions (outcome-changing only when both runs use the same policy family)."""
    out = []
    for f in (*OUTCOME_FIELDS, *INFO_FIELDS):
        if _field(a, f) != _field(b, f):
            out.append((f, a.get(f), b.get(f), f in OUTCOME_FIELDS))
    pa, pb = a.get(POLICY_FIELD) or {}, b.get(POLICY_FIELD) or {}
    same_family = pa.get("family") == pb.get("family")
    for k in sorted(set(pa) | set(pb)):
        if pa.get(k) != pb.get(k):
            out.append((f"{POLICY_FIELD}.{k}", pa.get(k), pb.get(k), same_family and k != "family"))
    return out


def short(v: Any, width: int = 60) -> str:
    """``v`` as one line of at most ``width`` characters (for the one-line refusals)."""
    text = json.dumps(v, sort_keys=True, default=str) if not isinstance(v, str) else v
    return text if len(text) <= width else text[: width - 1] + "…"


CONVENTIONS = f"{POLICY_FIELD}.conventions"


def conventions_items(text: Any) -> dict[str, str] | None:
    """A policy's conventions as the fingerprint stores them (the repr of a frozen dataclass, e.g.
    ``Conventions(render=256, images=Compose(steps=(Flip180(), ResizeWithPad(size=224))), chunk=10)``) as readable
    values by key: ``{"render": "256", "images": "Flip180 + ResizeWithPad(size=224)", "chunk": "10"}``; a call whose
    one argument is a tuple reads as its items joined by " + " ("none" when empty). None when ``text`` is not such a
    repr. Display only: the fingerprint keeps the repr."""
    import ast

    if not isinstance(text, str):
        return None
    try:
        node = ast.parse(text, mode="eval").body
    except SyntaxError:
        return None
    if not isinstance(node, ast.Call) or node.args or any(k.arg is None for k in node.keywords):
        return None
    return {k.arg: _readable(k.value) for k in node.keywords if k.arg}


def _readable(node) -> str:
    import ast

    if not isinstance(node, ast.Call):
        return ast.unparse(node)
    args = [*node.args, *(k.value for k in node.keywords)]
    if len(args) == 1 and isinstance(args[0], ast.Tuple):  # a pipeline of steps
        return " + ".join(_readable(e) for e in args[0].elts) or "none"
    inner = [ast.unparse(a) for a in node.args] + [f"{k.arg}={ast.unparse(k.value)}" for k in node.keywords]
    name = ast.unparse(node.func)
    return f"{name}({', '.join(inner)})" if inner else name


def show_difference(field: str, a: Any, b: Any, width: int = 40) -> tuple[str, str]:
    """Two values of ``field`` as a report prints them: the policy's conventions as the ``key=value`` pairs that
    differ (a run without conventions reads "none"), two texts from a little before they part (RoboCasa's
    ``initial_states`` under two splits share 400 characters), anything else ``short``."""
    if field == CONVENTIONS:
        ia, ib = conventions_items(a), conventions_items(b)
        if (ia is not None or a is None) and (ib is not None or b is None) and (ia or ib):
            ia, ib = ia or {}, ib or {}
            keys = [k for k in dict.fromkeys([*ia, *ib]) if ia.get(k) != ib.get(k)]

            def pairs(items: dict[str, str]) -> str:
                return ", ".join(f"{k}={items[k]}" for k in keys if k in items) or "none"

            return pairs(ia), pairs(ib)
    if isinstance(a, str) and isinstance(b, str):  # long words alike at first: from just before they part
        cut = len(os.path.commonprefix([a, b])) - 12
        if cut > 0:
            return short("…" + a[cut:], width), short("…" + b[cut:], width)
    return short(a, width), short(b, width)


def check_comparable(
    runs: Sequence[tuple[str, Mapping[str, Any] | None]], allow: bool = False, what: str = "paired"
) -> list[str]:
    """Refuse (one line naming the field) runs whose fingerprints differ in a field that changes outcomes, unless
    ``allow``; return the lines a report prints: every difference, and runs made before fingerprints existed."""
    lines, (label0, fp0) = [], runs[0]
    for label, fp in runs:
        if fp is None:
            lines.append(
                f"{label}: no protocol fingerprint (a real-robot run, an imported one, or one made before fingerprints were recorded); "
                "comparability not checked"
            )
    for label, fp in runs[1:]:
        if fp0 is None or fp is None:
            continue
        diffs = differences(fp0, fp)
        bad = [d for d in diffs if d[3]]
        if bad and not allow:
            f, va, vb, _ = bad[0]
            more = f" (and {len(bad) - 1} more field(s))" if len(bad) > 1 else ""
            sa, sb = show_difference(f, va, vb, width=60)
            raise ProtocolMismatchError(
                f"{label0} and {label} were made under different protocols, so they cannot be {what}: {f} is "
                f"{sa} vs {sb}{more}; re-run one under the other's protocol, or pass "
                "--allow-protocol-mismatch to go on (the output then lists every difference)"
            )
        for f, va, vb, changes in diffs:
            tag = "changes outcomes" if changes else "informational"
            sa, sb = show_difference(f, va, vb)
            lines.append(f"{label0} vs {label}: {f} differs ({tag}): {sa} vs {sb}")
    return lines


def protocol_section(lines: Sequence[str]) -> list[str]:
    """Markdown for a comparison or overlay report: the protocol differences found (nothing when there are none)."""
    if not lines:
        return []
    return ["## Protocol differences", "", *(f"- {x}" for x in lines), ""]
