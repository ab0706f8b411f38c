"""``indgen blockenv ablate``: the Table 1 ablations of docs/blockenv.md (Ind's loss, gate, mask, legality
head, training budget and data; MAML's head; TRM's tokens), at reduced scale, per seed with both CIs.

Each ablation is a list of variants of one method; a variant changes training (``extra`` options, updates,
demos per level) or only inference (``infer``: attributes set on the trained model, e.g. Ind's gate), and
variants that train alike share their trained models. Results land in a JSON file and in the section of
docs/results/blockenv_ablations.md between the ablation markers, so the document is regenerated from this script.
"""

from __future__ import annotations

import json
import re
import time
from dataclasses import dataclass, replace
from pathlib import Path

from indgen_vla.app.blockenv.data import rollout_oracle
from indgen_vla.app.blockenv.env import BlockEnvConfig, legal_grasps
from indgen_vla.app.blockenv.evaluate import evaluate_model
from indgen_vla.app.blockenv.fit import FitConfig, train
from indgen_vla.app.blockenv.reproduce import _pooled
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.registry import lookup
from indgen_vla.core.runs.records import atomic_write_json, atomic_write_text
from indgen_vla.core.stats.metrics import break_level


@dataclass(frozen=True)
class Variant:
    """One row of an ablation table."""

    label: str
    method: str
    extra: tuple[tuple[str, object], ...] = ()
    infer: tuple[tuple[str, object], ...] = ()
    steps: int | None = None
    demos_per_level: int | None = None


@dataclass(frozen=True)
class AblationScale:
    """The reduced scale every ablation runs at (the committed Table 1: 2000 updates, 100 episodes, L0–L10)."""

    seeds: tuple[int, ...] = (0, 1, 2)
    steps: int = 1000
    demos_per_level: int = 300
    episodes: int = 50
    eval_levels: tuple[int, ...] = tuple(range(7))
    gamma: float = 0.2

    def __post_init__(self) -> None:
        if len(self.seeds) < 2 or self.steps < 1 or self.episodes < 1 or self.demos_per_level < 1:
            raise ConfigError(
                "ablations need >= 2 seeds (for the CI over seeds), >= 1 step, episode and demo"
            )


_IND = "ind"
ABLATIONS: dict[str, tuple[str, list[Variant]]] = {
    "ind_legal_head": (
        "Where Ind's legality logits come from (all: legality BCE weight 1, gate 1, mask on)",
        [Variant("global (trunk read-out; Table 1 before)", _IND), Variant("local (3x3 conv on o_t; Table 1 now)", _IND,
         (("legal_head", "local"),)), Variant("both (sum)", _IND, (("legal_head", "both"),))],
    ),
    "ind_loss": (
        "Ind's legality loss: weight of the BCE term and of its rare positive cells (global head)",
        [Variant("no legality loss (weight 0)", _IND, (("legal_weight", 0.0),)),
         Variant("weight 1 (default)", _IND), Variant("weight 30", _IND, (("legal_weight", 30.0),)),
         Variant("weight 1, positives ×100", _IND, (("legal_pos_weight", 100.0),))],
    ),
    "ind_gate": (
        "Ind's inference: the additive gate's scale and the hard mask of empty cells (the same trained models "
        "as `ind_legal_head`'s global head, legality BCE weight 1)",
        [Variant(f"gate {g:g}, mask {'on' if m else 'off'}", _IND, infer=(("gate_scale", g), ("mask", m)))
         for g, m in ((0.0, False), (0.0, True), (1.0, False), (1.0, True), (10.0, True), (1000.0, True))],
    ),
    "ind_local_gate": (
        "The gate's scale with the local legality head (3x3 conv on o_t; one trained model per seed)",
        [Variant(f"local head, gate {g:g}", _IND, (("legal_head", "local"),), (("gate_scale", g),))
         for g in (0.0, 1.0, 10.0, 1000.0)],
    ),
    "ind_budget": (
        "Ind's training budget (optimiser updates; Table 1's local head)",
        [Variant(f"{n} updates", _IND, (("legal_head", "local"),), steps=n) for n in (500, 2000, 6000)],
    ),
    "ind_data": (
        "Ind's demonstrations per training level (Table 1's local head)",
        [Variant(f"{n} per level", _IND, (("legal_head", "local"),), demos_per_level=n) for n in (100, 300, 1000)],
    ),
    "maml_head": (
        "MAML's output head (first-order MAML, one inner step α = 0.05, adapted on 5 demos of the level)",
        [Variant("factored rows/cols/θ (before)", "maml"), Variant("joint (r, c, θ)", "maml", (("head", "joint"),))],
    ),
    "trm_patch": (
        "TRM's tokens: cells per patch side (1 would be one token per cell, the original TRM: ≈ 10× patch 3's "
        "cost, over this machine's budget; patch 2 is the nearest)",
        [Variant(f"patch {p}", "trm", (("patch", p),)) for p in (2, 3, 4, 6)],
    ),
}  # fmt: skip


FOCUS = {"maml_head": 2}  # the level whose per-seed numbers a table shows where L3 is not the question


def _train_key(v: Variant, scale: AblationScale, seed: int) -> str:
    return json.dumps([v.method, dict(v.extra), v.steps or scale.steps, v.demos_per_level or scale.demos_per_level,
                       seed], sort_keys=True)  # fmt: skip


def run_ablation(name: str, scale: AblationScale, log=print, models: dict | None = None) -> dict:
    """Train and evaluate every variant of ablation ``name`` for every seed; returns its result dict.

    ``models`` caches trained models by their training configuration, across ablations of one run.
    """
    import torch

    title, variants = lookup("BlockEnv ablation", name, ABLATIONS)
    torch.set_num_threads(1)
    env_cfg = BlockEnvConfig(grid_size=max(12, max(scale.eval_levels) + 1))
    models = {} if models is None else models
    rows, t0 = [], time.perf_counter()
    for v in variants:
        counts, top1 = {}, {}
        for seed in scale.seeds:
            key = _train_key(v, scale, seed)
            if key not in models:
                tc = FitConfig(v.method, seed=seed, steps=v.steps or scale.steps, extra=dict(v.extra),
                                 demos_per_level=v.demos_per_level or scale.demos_per_level)  # fmt: skip
                models[key] = (train(tc)[0], tc)
            model, tc = models[key]
            saved = {attr: getattr(model, attr) for attr, _ in v.infer}
            for attr, value in v.infer:
                setattr(model, attr, value)
            counts[seed] = evaluate_model(model, v.method, scale.eval_levels, scale.episodes, env_cfg,
                                          seed=1000 + seed, train_cfg=tc)  # fmt: skip
            if v.method == "ind":  # the legality head alone, on the oracle's states (inference options aside)
                for k in scale.eval_levels:
                    top1.setdefault(str(k), []).append(
                        legality_top1(model, k, scale.episodes, env_cfg, seed=1000 + seed)
                    )
            for attr, value in saved.items():  # the next variant sharing this model starts from its defaults
                setattr(model, attr, value)
            log(f"{name} | {v.label} | seed {seed}: "
                + " ".join(f"L{k} {s}/{n}" for k, (s, n) in counts[seed].items()))  # fmt: skip
        levels = {
            str(k): _pooled([counts[s][k] for s in scale.seeds], scale.seeds) for k in scale.eval_levels
        }
        brk = {
            str(s): break_level({k: c[0] / c[1] for k, c in counts[s].items()}, scale.gamma)
            for s in scale.seeds
        }
        rows.append({"label": v.label, "method": v.method, "extra": dict(v.extra), "infer": dict(v.infer),
                     "steps": v.steps or scale.steps, "demos_per_level": v.demos_per_level or scale.demos_per_level,
                     "levels": levels, "break_level": break_level({int(k): e["rate"] for k, e in levels.items()},
                                                                  scale.gamma),
                     "break_level_per_seed": brk, "legal_top1": top1})  # fmt: skip
    return {"name": name, "title": title, "scale": {**scale.__dict__, "seeds": list(scale.seeds),
            "eval_levels": list(scale.eval_levels)}, "wall_s": round(time.perf_counter() - t0, 1), "variants": rows}  # fmt: skip


def _brk(k) -> str:
    return "—" if k is None else f"L{k}"


def render(result: dict, focus: int = 3) -> str:
    """One markdown table: pooled % per level, then level ``focus`` per seed with both 95 % intervals."""
    sc = result["scale"]
    levels = sc["eval_levels"]
    n = sc["episodes"] * len(sc["seeds"])
    lines = [f"#### `{result['name']}` — {result['title']}", "",
             f"{len(sc['seeds'])} seeds × {sc['episodes']} episodes per level (n = {n} pooled per cell), "
             f"default {sc['steps']} updates and {sc['demos_per_level']} demos per level; "
             f"{result['wall_s'] / 60:.1f} min. Success %, pooled over seeds; at L{focus}: per seed, "
             "pooled Wilson 95 % CI, Student-t 95 % CI over seeds; break level pooled (per seed).", "",
             "| variant | " + " | ".join(f"L{k}" for k in levels)
             + f" | L{focus} per seed | L{focus} Wilson | L{focus} t over seeds | breaks at (per seed) |",
             "|" + "---|" * (len(levels) + 5)]  # fmt: skip
    top1 = [r for r in result["variants"] if r.get("legal_top1")]
    if top1:  # Ind's legality head alone: a column per level, the mean over seeds
        lines[2] += (" Legality top-1: how often the head's most confident occupied (cell, θ) is legal on the "
                     "oracle's states at L2 / L3 / L4 (mean over seeds; 1 = a perfect head).")  # fmt: skip
        lines[4] += " legality top-1 L2 / L3 / L4 |"
        lines[5] += "---|"
    for row in result["variants"]:
        f = row["levels"][str(focus)]
        seeds = " / ".join(f"{p['successes']}/{p['n']}" for p in f["per_seed"])
        t_ci = (
            "—" if f["seed_ci_low"] is None else f"{100 * f['seed_ci_low']:.0f}–{100 * f['seed_ci_high']:.0f}"
        )
        per_seed_brk = ", ".join(_brk(b) for b in row["break_level_per_seed"].values())
        lines.append(f"| {row['label']} | " + " | ".join(f"{100 * row['levels'][str(k)]['rate']:.0f}" for k in levels)
                     + f" | {seeds} | {100 * f['ci_low']:.0f}–{100 * f['ci_high']:.0f} | {t_ci} | "
                     f"{_brk(row['break_level'])} ({per_seed_brk}) |")  # fmt: skip
        if top1:
            t1 = row.get("legal_top1") or {}
            lines[-1] += (
                " "
                + " / ".join(
                    f"{sum(t1[str(k)]) / len(t1[str(k)]):.2f}" if str(k) in t1 else "—" for k in (2, 3, 4)
                )
                + " |"
            )
    return "\n".join(lines) + "\n"


def legality_top1(model, level: int, episodes: int, cfg: BlockEnvConfig, seed: int) -> float:
    """How often Ind's most confident occupied (cell, θ) is a legal grasp, over the oracle's states at ``level``.

    The states are the oracle's (the same whatever the model does), so this isolates the legality head: at
    every such state the legal grasps are exactly the chain tips or the exposed goal, each a right action.
    """
    import numpy as np
    import torch

    demos = rollout_oracle(np.full(episodes, level), cfg, np.random.default_rng([seed, level, 7]))
    obs = torch.as_tensor(demos.obs, dtype=torch.long)
    with torch.no_grad():
        legal = model(obs, torch.as_tensor(demos.levels))["legal"]  # (N, T, G, G, 2)
    legal = legal.masked_fill(~(obs != 0)[..., None].expand_as(legal), -np.inf).flatten(2)
    truth = torch.as_tensor(legal_grasps(demos.obs)).flatten(2)
    hit = truth.gather(-1, legal.argmax(-1, keepdim=True))[..., 0]
    valid = torch.as_tensor(demos.mask).bool()
    return float(hit[valid].float().mean())


BEGIN, END = "<!-- ablations:begin (indgen blockenv ablate writes this) -->", "<!-- ablations:end -->"


def replace_section(doc: Path, begin: str, end: str, body: str, what: str) -> None:
    """Rewrite what lies between the ``begin`` and ``end`` marker lines of ``doc`` (generated doc sections)."""
    text = doc.read_text()
    if begin not in text or end not in text:
        raise ConfigError(f"{doc} has no {what} markers; add the lines {begin!r} and {end!r} where tables go")
    atomic_write_text(doc, re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: f"{begin}\n\n{body}\n{end}",
                                  text, flags=re.S))  # fmt: skip


def write_doc(results: dict[str, dict], doc: Path) -> None:
    """Replace the section between BEGIN and END of ``doc`` by the tables of ``results`` (in ABLATIONS order)."""
    tables = "\n".join(render(results[k], FOCUS.get(k, 3)) for k in ABLATIONS if k in results)
    replace_section(doc, BEGIN, END, tables, "ablation")


def ablate(names: list[str], scale: AblationScale, results_path: Path, doc: Path | None, log=print) -> dict:
    """Run ``names`` (merging into the results JSON already at ``results_path``) and rewrite the doc section."""
    results = json.loads(results_path.read_text()) if results_path.exists() else {}
    models: dict[str, tuple] = {}
    for name in names:
        results[name] = run_ablation(name, scale, log, models)
        results_path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_json(results_path, results)  # after each, whole: a kill never costs the other ablations
        if doc is not None:
            write_doc(results, doc)
    return results


def quick_scale() -> AblationScale:
    """A tiny smoke scale for tests."""
    return replace(
        AblationScale(), seeds=(0, 1), steps=3, demos_per_level=4, episodes=3, eval_levels=(0, 2, 3)
    )
