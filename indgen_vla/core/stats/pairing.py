"""Episode pairing of two runs (shared by ``indgen compare`` for two runs and for two groups of runs)."""

from __future__ import annotations

PAIR_KEY = ("scene", "task", "axis", "level", "episode")


def pair_episodes(ea, eb, axis: str) -> tuple[dict[int, list[tuple[bool, bool]]] | None, str]:
    """Episode-by-episode pairs of one axis, or None and the reason when the runs are not paired.

    Runs are paired when they planned the same episodes (same scene, tasks, levels and episode indices) and
    every episode has the same seed and level parameter in both, i.e. the same initial state. Pairs are the
    episodes finished ``ok`` in both runs; an episode that errored in either run drops out of its pair.
    """
    a, b = ea[ea["axis"] == axis], eb[eb["axis"] == axis]
    ia, ib = a.set_index(list(PAIR_KEY)), b.set_index(list(PAIR_KEY))
    if ia.index.has_duplicates or ib.index.has_duplicates:
        return None, "a run holds duplicate episodes"
    if set(ia.index) != set(ib.index):
        return None, (
            f"the runs do not hold the same episodes on {axis} ({len(ia)} vs {len(ib)}: other tasks, levels or "
            "--episodes, or a run not finished)"
        )
    ib = ib.loc[ia.index]
    if (ia["seed"].to_numpy() != ib["seed"].to_numpy()).any():
        return None, f"episode seeds differ on {axis} (different --seed)"
    pa, pb = ia["param"].to_numpy(dtype=float), ib["param"].to_numpy(dtype=float)
    if (abs(pa - pb) > 1e-9 * (1 + abs(pa))).any():
        return None, f"level parameters differ on {axis} (different --step, or a real set-up's YAML)"
    both = ((ia["status"] == "ok") & (ib["status"] == "ok")).to_numpy()
    pairs: dict[int, list[tuple[bool, bool]]] = {int(k): [] for k in ia.index.get_level_values("level")}
    for key, sa, sb in zip(ia.index[both], ia["success"][both], ib["success"][both], strict=True):
        pairs[int(key[3])].append((bool(sa), bool(sb)))
    return pairs, f"{int(both.sum())} episode pairs ({int((~both).sum())} dropped: error in either run)"
