"""``indgen real plan``: a normal run directory for a real-robot axis, and the order its episodes run in.

The manifest has the shape ``indgen evaluate`` writes (scene ``real:<set-up>``, one task, one axis, levels,
episodes, seed; the sequential rule under ``plan.adaptive``), so ``indgen report`` and ``indgen compare`` read it
unchanged; the set-up YAML, operator, robot and policy go under ``real``. Episode i gets the engine's seed for
(run seed, scene, task, i), so two runs of the same set-up and seed are paired episode by episode in ``compare``.

Which episode comes next is a pure function of the manifest and the journal (``queue``): a fixed design runs every
planned episode; ``--adaptive`` asks the engine's rule (``indgen_vla.core.stats.sprt.plan_next``) for the episodes it
still needs: the SPRT's (kstar, curve), or the paper's own design (``until-failure``: every trial of a level, levels
in order until the first observed rate < γ), which a set-up's ``stopping`` makes its default. ``interleaved``
order cycles through the open levels (a seeded shuffle per cycle, so drift over the session does not line up with
the level); ``blocked`` finishes one level before the next. A voided episode is re-queued: one cycle later when
interleaved, at the end of its level's block when blocked.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import random
import sys
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.app.config_fields import check_types, option
from indgen_vla.app.real.setup import ORDERS, RealAxis, RealSetup, load_setup, presets, setup_from_dict
from indgen_vla.app.real.store import State
from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.seeding import episode_seed
from indgen_vla.core.reporting.caveats import design_caveats
from indgen_vla.core.runs.records import RunDir, atomic_write_text
from indgen_vla.core.stats.sprt import (
    UNTIL_FAILURE,
    Decision,
    Plan,
    SequentialRule,
    UntilFailure,
    make_rule,
    plan_entry,
    plan_next,
    rule_from_plan,
)

PROTOCOL = "protocol.md"
# the flags of ``indgen real plan`` in its --help order
PLAN_FLAGS = ("setup", "axis", "levels", "episodes", "order", "adaptive", "adaptive_delta", "adaptive_alpha",
              "round_size", "gamma", "seed", "policy", "operator", "robot", "data_regime", "out")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class RealPlanConfig:
    """Everything ``indgen real plan`` needs; validated on construction."""

    setup: str = option(help=f"set-up YAML path or preset ({', '.join(presets())})", required=True)
    out: str = option(help="run directory to create", required=True)
    axis: str | None = option(None, "axis of the set-up (default: its only axis)")
    levels: str | None = option(None, "levels like 0:4 or 0,1,2 (default: all of the set-up's)")
    episodes: int = option(
        10, "episodes per level (paper: 10; the cap with --adaptive kstar/curve)", type=int
    )
    order: str | None = option(None, "interleave levels or run them in blocks (default: interleaved where the "
                               "set-up's change is cheap, blocked where slow)", choices=list(ORDERS))  # fmt: skip
    seed: int = option(0, "run seed: episode seeds (pairing) and the shuffle (0)", type=int)
    adaptive: str | None = option(None, "until-failure: the paper's design (--episodes at each level, levels in "
                                  "order, stop after the first observed rate < γ; the default of the set-ups that "
                                  "name it, e.g. stack, scale); kstar/curve: stop each level once the sequential rule "
                                  "decides it (as 'indgen evaluate --adaptive'); off: every level",
                                  choices=["kstar", "curve", "until-failure", "off"])  # fmt: skip
    gamma: float = option(0.2, "break threshold γ (paper: 0.2)", type=float)
    adaptive_delta: float = option(0.1, "indifference half-width around γ (0.1)", type=float)
    adaptive_alpha: float = option(0.025, "error rate of each verdict, α = β (0.025)", type=float)
    round_size: int = option(5, "episodes between two looks of the rule (5)", type=int)
    operator: str = option("", "who judges the episodes")
    robot: str = option("", "the robot (default: the set-up's)")
    policy: str = option("", "name of the policy/checkpoint you run, e.g. pi05-droid", required=True)
    data_regime: str = option("", "label of the training data regime, e.g. h-only")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if not self.out:
            raise ConfigError("--out is required: the run directory 'indgen real record' will fill")
        if not self.policy.strip():
            raise ConfigError("--policy NAME is required: name the checkpoint you run (e.g. pi05-droid), "
                              "so reports and comparisons can tell runs apart")  # fmt: skip
        if isinstance(self.episodes, bool) or not isinstance(self.episodes, int) or self.episodes < 1:
            raise ConfigError(f"--episodes must be a positive integer, got {self.episodes!r}")
        if self.order is not None and self.order not in ORDERS:
            raise ConfigError(f"--order must be one of {', '.join(ORDERS)}, got {self.order!r}")
        if not 0 < self.gamma < 1:
            raise ConfigError(f"--gamma must be in (0, 1), got {self.gamma}")
        if self.adaptive not in (None, OFF):
            self.rule(self.adaptive)

    def rule(self, mode: str) -> SequentialRule | UntilFailure:
        return make_rule(
            mode, self.gamma, self.adaptive_delta, self.adaptive_alpha, self.round_size, self.episodes
        )

    def mode(self, setup: RealSetup) -> str | None:
        """The stopping rule: --adaptive, else the set-up's ``stopping`` (the paper's presets: until-failure);
        None (``off``, or neither given): every planned episode of every level."""
        mode = self.adaptive if self.adaptive is not None else setup.stopping
        return None if mode in (None, OFF) else mode


OFF = "off"  # --adaptive off: the plain fixed design even where the set-up names a stopping rule


def parse_levels(text: str | None, axis: RealAxis) -> list[int]:
    """``0:4`` (inclusive), ``0,1,2`` or ``2``, inside the set-up's 0..K."""
    if text is None:
        return list(range(axis.max_level + 1))
    s = str(text).strip()
    try:
        if ":" in s:
            lo, hi = (int(x) for x in s.split(":", 1))
            if lo > hi:
                raise ConfigError(f"--levels {s!r}: start {lo} is after end {hi}; write it as {hi}:{lo}")
            levels = list(range(lo, hi + 1))
        else:
            levels = [int(x) for x in s.split(",") if x.strip()]
    except ValueError:
        raise ConfigError(f"--levels {text!r} is not a range like 0:4 or a list like 0,1,2") from None
    bad = [k for k in levels if not 0 <= k <= axis.max_level]
    if not levels or bad:
        raise ConfigError(
            f"--levels {text!r}: axis {axis.name} of this set-up has levels 0..{axis.max_level}"
        )
    return sorted(set(levels))


def build_manifest(
    cfg: RealPlanConfig, setup: RealSetup, axis: RealAxis, levels: list[int], run_id: str
) -> dict:
    mode = cfg.mode(setup)
    if mode == UNTIL_FAILURE and cfg.order == "interleaved":
        raise ConfigError("--adaptive until-failure runs one level at a time (the next only after the last one's "
                          "trials): leave out --order interleaved")  # fmt: skip
    order = cfg.order or ("interleaved" if axis.change == "cheap" and mode != UNTIL_FAILURE else "blocked")
    scene = f"real:{setup.name}"
    plan: dict[str, Any] = {
        "policy": cfg.policy, "scene": scene, "tasks": [setup.task], "axes": [axis.name],
        "levels": {axis.name: levels}, "episodes": cfg.episodes, "seed": cfg.seed, "order": order,
        "params": {str(k): axis.level(k).param for k in levels}, "data_regime": cfg.data_regime,
    }  # fmt: skip
    if mode:
        plan["adaptive"] = plan_entry(mode, cfg.rule(mode))
    return {
        "run_id": run_id,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "policy": cfg.policy,
        "data_regime": cfg.data_regime,
        "scene": scene,
        "seed": cfg.seed,
        "plan": plan,
        "axes": {axis.name: axis.as_axis_dict()},
        "config": dataclasses.asdict(cfg),
        "real": {
            "setup_name": setup.name,
            "setup_source": setup.source,
            "setup_yaml": setup.text,
            "instruction": setup.instruction,
            "operator": cfg.operator,
            "robot": cfg.robot or setup.robot,
            "policy": cfg.policy,
        },  # fmt: skip
        "command": " ".join(["indgen", *sys.argv[1:]]) if sys.argv and "indgen" in sys.argv[0] else "",
    }


def plan_run(cfg: RealPlanConfig) -> Path:
    """Write (or re-open, when the plan is the same) the run directory and its printable protocol."""
    setup = load_setup(cfg.setup)
    axis = setup.axis(cfg.axis)
    levels = parse_levels(cfg.levels, axis)
    out = Path(cfg.out)
    old = RunDir(out)
    run_id = (old.manifest.get("run_id") if (out / "manifest.json").exists() else None) or uuid.uuid4().hex[
        :12
    ]
    run = RunDir.create_or_resume(out, build_manifest(cfg, setup, axis, levels, run_id))
    atomic_write_text(run.path / PROTOCOL, protocol_markdown(RealRun(run)))
    return run.path


class RealRun:
    """A planned real run: its set-up and plan, read back from the manifest (never from the preset on disk)."""

    def __init__(self, run: RunDir):
        self.run = run
        m = run.manifest
        if "real" not in m or not str(m.get("scene", "")).startswith("real:"):
            raise RunDirError(
                f"{run.path} was not planned by 'indgen real plan'; plan a real run there first"
            )
        self.manifest = m
        self.plan = m["plan"]
        self.setup = setup_from_dict(_yaml(m["real"]["setup_yaml"]), source=m["real"]["setup_source"])
        self.axis = self.setup.axis(self.plan["axes"][0])
        self.task = self.plan["tasks"][0]
        self.levels: list[int] = list(self.plan["levels"][self.axis.name])
        self.episodes: int = int(self.plan["episodes"])
        self.order: str = self.plan["order"]
        self.mode: str | None = (self.plan.get("adaptive") or {}).get("mode")
        self.rule = rule_from_plan(self.plan["adaptive"], self.episodes) if self.mode else None
        self.seeds = {i: episode_seed(m["seed"], m["scene"], self.task, i) for i in range(self.episodes)}
        self.params = {k: self.axis.level(k).param for k in self.levels}
        self.gamma: float = self.rule.gamma if self.rule else float(m.get("config", {}).get("gamma", 0.2))

    def caveats(self) -> list[str]:
        """What this plan can never show, whatever the operator records: protocol.md's and ``real status``' first
        lines (``caveats.design_caveats``)."""
        tested = (
            0 if 0 not in self.levels else 1 if self.mode else len(self.levels) - 1
        )  # a walk may stop early
        where = f"set-up {self.setup.name}, `{self.axis.name}`, task {self.task}"
        out = design_caveats(where, self.episodes, tested, self.gamma, self.mode in (None, UNTIL_FAILURE))
        if 0 not in self.levels:  # real.md step 1: the training set-up first
            out.append(f"**No level 0** ({where}): without the training set-up nothing shows the policy solves it and "
                       f"no level is tested against T0; plan --levels 0:{self.levels[-1]}.")  # fmt: skip
        return out

    @classmethod
    def open(cls, path: str | Path) -> RealRun:
        """Open a planned run (its Parquet view is not read: the journal is the source of truth)."""
        run = RunDir(path)
        if not (run.path / "manifest.json").is_file():
            raise RunDirError(
                f"{run.path} is not a run directory; create it with 'indgen real plan --out {run.path}'"
            )
        return cls(run)

    def sequential(self, state: State) -> Plan | None:
        """The sequential rule's view of the counted outcomes (voids never count: they are re-run)."""
        if self.rule is None:
            return None
        outcomes = {k: {} for k in self.levels}
        for (k, i), e in state.counted.items():
            outcomes.setdefault(k, {})[i] = e.kind == "success"
        return plan_next(self.rule, self.levels, outcomes, self.mode, signed=False)

    def queue(self, state: State) -> list[tuple[int, int]]:
        """(level, episode) still to run, in order; empty when the run is complete."""
        if self.rule is not None:
            seq = self.sequential(state)
            pending = [(k, i) for k, eps in seq.to_run.items() for i in eps]
        else:
            pending = [
                (k, i) for k in self.levels for i in range(self.episodes) if (k, i) not in state.counted
            ]
        rank = {k: r for r, k in enumerate(sorted(self.levels))}

        def key(item: tuple[int, int]):
            k, i = item
            voids = len(state.voids.get(item, ()))
            if self.order == "blocked":
                return (rank[k], voids, i)
            return (
                i + voids,
                voids,
                self._cycle_position(i + voids, k),
                i,
            )  # re-runs after the cycle's fresh ones

        return sorted(pending, key=key)

    def _cycle_position(self, cycle: int, level: int) -> int:
        perm = sorted(self.levels)
        random.Random(episode_seed(self.manifest["seed"], self.manifest["scene"], "order", cycle)).shuffle(
            perm
        )
        return perm.index(level)

    def not_run(self, seq: Plan, level: int) -> str:
        """Why the rule has not decided ``level`` (kstar and until-failure walk the levels upward): "not needed" past
        a level that ended the walk (decided broken; until-failure: observed below γ), "not reached" while a level
        below it is still running."""
        if isinstance(self.rule, UntilFailure):
            ended = any(d.final and self.rule.stops(d) for k, d in seq.decisions.items() if k < level)
        else:
            ended = any(d.verdict == "broken" for k, d in seq.decisions.items() if k < level)
        return "not needed" if ended else "not reached"

    def decision(self, state: State, level: int) -> Decision | None:
        seq = self.sequential(state)
        return None if seq is None else seq.decisions.get(level)


def _yaml(text: str):
    import yaml

    return yaml.safe_load(text)


def protocol_markdown(r: RealRun) -> str:
    """The operator's printable sheet: task, fixed conditions, each level's set-up, the order and the rule."""
    s, a = r.setup, r.axis
    lines = [f"# Real-robot protocol: {s.name} / {a.name}", "", *[x for c in r.caveats() for x in (c, "")],
             f"- task `{r.task}`: \"{s.instruction}\"", f"- robot: {r.manifest['real']['robot'] or 'not named'}; "
             f"policy: {r.manifest['policy']}; operator: {r.manifest['real']['operator'] or 'not named'}",
             f"- fixed: {s.base or 'not stated'}", f"- axis `{a.name}`: {a.description} ({a.unit})", "",
             "| level | param | set-up |", "|---|---|---|"]  # fmt: skip
    lines += [f"| {k} | {a.param_text(k)} | {a.level(k).setup} |" for k in r.levels]
    lines.append("")
    if s.placements:
        lines += ["Start placements (episode i uses placement i mod n, the same at every level):", ""]
        lines += [f"{j}. {p}" for j, p in enumerate(s.placements)] + [""]
    lines.append(f"Order: {r.order} ({'levels cycled, shuffled per cycle' if r.order == 'interleaved' else 'one level at a time'}).")  # fmt: skip
    if r.mode == UNTIL_FAILURE:
        lines.append(
            f"The paper's design (§5.3): {r.episodes} episodes at each level, levels in order, and the run stops after "
            f"the first level whose observed rate is below γ = {r.rule.gamma:g} (levels past it never run). That "
            "break is observed, not decided by a statistical test: the report gives its 95 % CI."
        )
    elif r.rule is not None:
        rule = r.rule
        lines.append(
            f"Adaptive ({r.mode}): rounds of {rule.round_size} episodes, at most {r.episodes} per level; a level is "
            f"decided broken (S < γ = {rule.gamma}) or intact by a truncated SPRT with indifference ±{rule.delta} and "
            f"error rates α = β = {rule.alpha} (docs/adaptive.md)"
            + ("; levels past a decided break are not run." if r.mode == "kstar" else ".")
        )
    else:
        lines.append(f"Fixed design: {r.episodes} episodes per level, {r.episodes * len(r.levels)} in all.")
    lines += ["", "Record outcomes with `indgen real record RUN`; report with `indgen report RUN`.", ""]
    return "\n".join(lines)
