"""The break level with its uncertainty (three-way verdicts, k* status) and the continuous break point.

Per level: "broken" when the CI's upper bound is below γ, "intact" when its lower bound is at least γ,
otherwise "undetermined". The continuous break point is where the fitted success curve crosses γ in one
direction: a monotone logistic fit of success on |level|, or centered isotonic regression when the logistic
fit is poor (wrong slope sign, separation, or deviance lack-of-fit p < 0.05), with a seeded bootstrap CI over
episodes (multi-stage over clusters such as tasks or training seeds when given). docs/adaptive.md explains.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.crossing import crossing, isotonic_crossing, logistic_crossings
from indgen_vla.core.stats.frames import group_items, py
from indgen_vla.core.stats.metrics import break_level


def verdict_from_ci(ci_low: float, ci_high: float, gamma: float) -> str:
    """Three-way verdict of one level: broken (upper < γ), intact (lower ≥ γ), else undetermined."""
    if not 0 < gamma <= 1:
        raise ConfigError(f"gamma must be in (0, 1], got {gamma}")
    if ci_high < gamma:
        return "broken"
    if ci_low >= gamma:
        return "intact"
    return "undetermined"


def signed_level(k: int, minus: str = "-") -> str:
    """A level as printed beside a direction: "+2", "-1", "0" (``minus``: e.g. "−" in tables and figures)."""
    return f"+{k}" if k > 0 else f"{minus}{-k}" if k < 0 else "0"


def kstar_status(
    verdicts: Mapping[int, str], order: Sequence[int], run: Collection[int] | None = None
) -> dict:
    """Where k* can be, given per-level verdicts walked in `order` (outward from level 0, one direction).

    The earliest possible break is the first level not "intact"; the latest is the first "broken" one.
    k* is determined when they coincide. A level missing from `verdicts` (not run) or still open counts
    as unknown. Returns {"earliest", "latest", "determined", "text"}; latest None = beyond the last level.
    The text speaks only of the levels in ``run`` (those with a finished episode; default: those in
    ``verdicts``) and names the planned levels of ``order`` not run yet (an adaptive run stopped or running).
    """
    earliest = latest = None
    for k in order:
        v = verdicts.get(k)
        if v == "intact":
            continue
        if earliest is None:
            earliest = k
        if v == "broken":
            latest = k
            break
    last = order[-1] if order else None
    if earliest is None:
        text = f"no break through {signed_level(last)}, determined" if last is not None else "no levels"
        return {"earliest": None, "latest": None, "determined": last is not None, "text": text}
    if latest == earliest:
        return {
            "earliest": earliest,
            "latest": latest,
            "determined": True,
            "text": f"k* = {signed_level(earliest)}, determined",
        }
    ran = set(verdicts) if run is None else set(run)
    if latest is None:
        text = f"k* at or beyond {signed_level(earliest)} ({_open_text(order, ran)})"
    else:
        lo, hi = sorted((earliest, latest))
        holes = _levels_text([k for k in order[: order.index(latest)] if k not in ran])
        text = f"k* ∈ [{signed_level(lo)}, {signed_level(hi)}]" + (f" ({holes} not run)" if holes else "")
    return {"earliest": earliest, "latest": latest, "determined": False, "text": text}


def _levels_text(levels: Sequence[int]) -> str:
    return ", ".join(signed_level(k) for k in levels)


def _open_text(order: Sequence[int], ran: set[int]) -> str:
    """Why no break is decided yet, naming only levels that ran: "no level through +2 is decided broken; +3 not
    run" (a level planned but not run is never counted as tested)."""
    done = [k for k in order if k in ran]
    missing = _levels_text([k for k in order if k not in ran])
    if not done:
        return f"no level run yet; {missing} planned"
    tail = f"; {missing} not run" if missing else ""
    return f"no level through {signed_level(done[-1])} is decided broken{tail}"


def kstar_spread(ks: Sequence[int | None | str], minus: str = "-") -> str:
    """Per-task k* of one direction as one line, e.g. "L1 ×3, L2 ×5, none ×2 (10 tasks; median L2)": what a
    several-task adaptive run can state where its pooled curve cannot (a task's ladder stops at its break).

    ``ks``: each task's k*: a level, None (no break in range, so beyond every level) or "undetermined". The median
    is the middle task's k* with None ranked past every level; it is left out while any task is undetermined."""
    if not ks:
        return "no tasks"

    def name(k: int | None) -> str:  # as the per-task k* cells print it (report._fmt_break)
        return "none" if k is None else f"L{k}".replace("-", minus)

    broken = sorted((k for k in ks if isinstance(k, int)), key=abs)
    n_none = sum(k is None for k in ks)
    n_open = len(ks) - len(broken) - n_none
    parts = [f"{name(k)} ×{broken.count(k)}" for k in dict.fromkeys(broken)]
    parts += [f"none ×{n_none}"] * bool(n_none) + [f"undetermined ×{n_open}"] * bool(n_open)
    median = ""
    if not n_open:  # every task decided, so ranked is non-empty
        ranked = broken + [None] * n_none  # sorted outward; None (no break in range) past every level
        lo, hi = ranked[(len(ranked) - 1) // 2], ranked[len(ranked) // 2]
        median = f"; median {name(lo)}" + (f" to {name(hi)}" if hi != lo else "")
    return f"{', '.join(parts)} ({len(ks)} task{'s' * (len(ks) != 1)}{median})"


def fixed_run_status(levels: Sequence[Mapping], gamma: float, signed: bool | None = None) -> dict:
    """For a fixed-design run's summary levels ({level, rate, ci_low, ci_high, n}): each level's verdict and,
    per direction, the point k* (metrics.break_level) with its status. Levels with n == 0 stay "undetermined"."""
    verdicts = {
        int(r["level"]): verdict_from_ci(r["ci_low"], r["ci_high"], gamma)
        if r.get("n", 1)
        else "undetermined"
        for r in levels
    }
    rates = {int(r["level"]): float(r["rate"]) for r in levels if r.get("n", 1)}
    ran = {int(r["level"]) for r in levels if r.get("n", 1) or r.get("errors")}
    if signed is None:
        signed = any(k < 0 for k in verdicts)
    out: dict = {"verdicts": verdicts, "kstar": {}}
    for direction, sign in (("pos", 1), ("neg", -1)) if signed else (("pos", 1),):
        order = sorted((k for k in verdicts if sign * k >= 0), key=abs)
        status = kstar_status(verdicts, order, ran)
        status["k"] = break_level({k: v for k, v in rates.items() if sign * k >= 0}, gamma)
        out["kstar"][direction] = status
    return out


@dataclass(frozen=True)
class Cell:
    """Counts of one level in one cluster (e.g. one task of one training seed's run)."""

    level: int
    param: float
    successes: int
    n: int
    cluster: tuple = ()

    def __post_init__(self):
        if self.n < 0 or not 0 <= self.successes <= self.n:
            raise ConfigError(f"level {self.level}: need 0 <= successes <= n, got {self.successes}/{self.n}")


def cell_param(params: Sequence[float]) -> float:
    """A cell's parameter: its episodes' one value, or their mean where each episode has its own (RoboCasa's pick_x
    offset in each episode's kitchen)."""
    first = float(params[0])
    return first if max(params) - min(params) <= 1e-12 else sum(map(float, params)) / len(params)


def cells_from_records(records: Iterable[Mapping], cluster_keys: Sequence[str] = ()) -> list[Cell]:
    """Aggregate episode records (dicts with level, param, success[, status]) into cells; errors skipped."""
    acc: dict[tuple, list] = {}
    for r in records:
        if r.get("status", "ok") != "ok":
            continue
        try:
            key = (tuple(r[c] for c in cluster_keys), int(r["level"]))
            a = acc.setdefault(key, [[], 0, 0])
            a[0].append(float(r["param"]))
            a[1] += bool(r["success"])
            a[2] += 1
        except KeyError as e:
            raise ConfigError(
                f"episode record lacks column {e.args[0]!r} needed for the break point"
            ) from None
    return [
        Cell(level=lv, param=cell_param(p), successes=s, n=n, cluster=c)
        for (c, lv), (p, s, n) in sorted(acc.items(), key=str)
    ]


def cells_from_frame(df, cluster_keys: Sequence[str] = ()) -> list[Cell]:
    """``cells_from_records`` of an episode table, grouped in one vectorised pass instead of a Python loop over its
    rows: the same cells in the same order (each cell's param is ``cell_param`` of its rows')."""
    ok = df[df["status"] == "ok"] if "status" in df else df
    if not len(ok):
        return []
    need = [c for c in (*cluster_keys, "level", "param", "success") if c not in ok]
    if need:
        raise ConfigError(f"episode record lacks column {need[0]!r} needed for the break point")
    ok = ok.assign(_level=ok["level"].astype("int64"), _success=ok["success"].astype(bool))
    keys = [*cluster_keys, "_level"]
    params = ok.groupby(keys, sort=False, dropna=False)["param"].agg(list)
    acc = {(tuple(py(v) for v in k[:-1]), py(k[-1])): [cell_param(p), 0, 0] for k, p in group_items(params)}
    grouped = ok.groupby(keys, sort=False, dropna=False)["_success"]
    for (*k, lv), s in group_items(grouped.sum()):
        acc[(tuple(k), lv)][1] = s
    for (*k, lv), n in group_items(grouped.size()):
        acc[(tuple(k), lv)][2] = n
    return [
        Cell(level=lv, param=p, successes=s, n=n, cluster=c)
        for (c, lv), (p, s, n) in sorted(acc.items(), key=str)
    ]


def _to_param(xc: float, x: np.ndarray, params: np.ndarray) -> float:
    if not math.isfinite(xc):
        return xc
    return float(np.interp(xc, x, params))


def _boot_weights(clusters: list[tuple], n_boot: int, rng: np.random.Generator) -> np.ndarray:
    """Multi-stage cluster bootstrap multiplicities (n_boot × clusters): resample the first key's values,
    then the second key's values within each, and so on; a lone cluster keeps weight 1."""
    depth = len(clusters[0]) if clusters else 0
    w = np.ones((n_boot, len(clusters)), dtype=np.int64)

    def stage(members: list[int], level: int, mult: np.ndarray) -> None:
        if level == depth:
            for m in members:
                w[:, m] = mult
            return
        groups: dict = {}
        for m in members:
            groups.setdefault(clusters[m][level], []).append(m)
        keys = sorted(groups, key=str)
        if len(keys) == 1:
            stage(groups[keys[0]], level + 1, mult)
            return
        draws = np.stack([rng.multinomial(int(t) * len(keys), [1 / len(keys)] * len(keys)) for t in mult])
        for j, k in enumerate(keys):
            stage(groups[k], level + 1, draws[:, j])

    stage(list(range(len(clusters))), 0, np.ones(n_boot, dtype=np.int64))
    return w


def _interval(values: np.ndarray, conf: float) -> list[float | None]:
    """Percentile interval by order statistics (inf-safe); an infinite bound is reported as None."""
    v = np.sort(values[~np.isnan(values)])
    if len(v) == 0:
        return [None, None]
    q = (1 - conf) / 2
    lo, hi = v[int(math.floor(q * (len(v) - 1)))], v[int(math.ceil((1 - q) * (len(v) - 1)))]
    return [float(lo) if math.isfinite(lo) else None, float(hi) if math.isfinite(hi) else None]


def _direction_data(cells: Sequence[Cell], direction: str):
    sign = 1 if direction == "pos" else -1
    mine = [c for c in cells if c.level * sign >= 0]
    levels = sorted({c.level * sign for c in mine})
    clusters = sorted({c.cluster for c in mine}, key=str)
    ci = {c: i for i, c in enumerate(clusters)}
    li = {lv: i for i, lv in enumerate(levels)}
    s = np.zeros((len(clusters), len(levels)))
    n = np.zeros((len(clusters), len(levels)))
    params = np.zeros(len(levels))
    count = np.zeros(len(levels))  # a level's parameter may differ per task: report their mean
    for c in mine:
        s[ci[c.cluster], li[c.level * sign]] += c.successes
        n[ci[c.cluster], li[c.level * sign]] += c.n
        params[li[c.level * sign]] += c.param
        count[li[c.level * sign]] += 1
    return sign, np.array(levels, dtype=float), params / count, clusters, s, n


def _boot_crossings(cells, direction, gamma, method, n_boot, rng):
    sign, x, params, clusters, s, n = _direction_data(cells, direction)
    ss, nn = s.sum(0), n.sum(0)
    xc, used, why = crossing(x, ss, nn, gamma, method)
    flat = bool(((ss[nn > 0] == 0) | (ss[nn > 0] == nn[nn > 0])).all())  # every level at 0 % or 100 %
    w = _boot_weights(clusters, n_boot, rng)
    with np.errstate(invalid="ignore", divide="ignore"):
        p_hat = np.where(n > 0, s / np.maximum(n, 1), 0.0)
    bs = np.zeros((n_boot, len(x)))
    bn = (w @ n).astype(float)
    for c in range(len(clusters)):
        bs += rng.binomial((w[:, c : c + 1] * n[c]).astype(np.int64), p_hat[c])
    boot = np.full(n_boot, np.nan)
    ok = np.zeros(n_boot, dtype=bool)
    if used == "logistic":
        boot, ok = logistic_crossings(x, bs, bn, gamma)
    n_iso = 0
    for r in np.flatnonzero(~ok):
        if (bn[r] > 0).sum() < 2:
            continue
        boot[r] = isotonic_crossing(x[bn[r] > 0], bs[r][bn[r] > 0], bn[r][bn[r] > 0], gamma)
        n_iso += 1
    return sign, x, params, clusters, xc, used, why, boot, n_iso, int(n.sum()), flat


def break_point(
    cells: Sequence[Cell],
    gamma: float = 0.2,
    *,
    method: str = "auto",
    n_boot: int = 1000,
    conf: float = 0.95,
    seed: int = 0,
    cluster_names: Sequence[str] = (),
) -> dict:
    """Continuous break point per direction in the docs/contracts.md shape {"pos": {param, level, ci, ...}, "neg": ...}.

    `cells` carry each level's counts per cluster (cluster () = one pool of episodes; (task,) or
    (seed, task) for a multi-stage bootstrap; `cluster_names` labels those keys in "resampled").
    level/param are None when S does not cross γ inside the evaluated levels ("below" = already under γ at
    the first level, "above" = never under γ).
    """
    if not 0 < gamma < 1:
        raise ConfigError(f"gamma must be in (0, 1), got {gamma}")
    if n_boot < 1 or not 0 < conf < 1:
        raise ConfigError(f"need n_boot >= 1 and 0 < conf < 1, got n_boot={n_boot}, conf={conf}")
    if not cells:
        raise ConfigError("the break point needs episode counts; the run has no finished episodes")
    rng = np.random.default_rng(seed)
    signed = any(c.level < 0 for c in cells)
    out = {}
    for direction in ("pos", "neg") if signed else ("pos",):
        try:
            sign, x, params, clusters, xc, used, why, boot, n_iso, n_eps, flat = _boot_crossings(
                cells, direction, gamma, method, n_boot, rng
            )
        except ConfigError as e:
            if "at least two levels" not in str(e):
                raise
            out[direction] = {
                "level": None,
                "param": None,
                "ci": {"level": [None, None], "param": [None, None], "conf": conf},
                "crossing": None,
                "method": None,
                "why": str(e),
            }
            continue
        lv_ci = _widened(_interval(boot, conf), x, xc, "separated" in why or flat)
        par = [_to_param(v, x, params) if v is not None else None for v in lv_ci]
        lv_ci = [sign * v if v is not None else None for v in lv_ci]
        if sign < 0:
            lv_ci, par = lv_ci[::-1], par[::-1]
        finite = math.isfinite(xc)
        out[direction] = {
            "level": sign * xc if finite else None,
            "param": _to_param(xc, x, params) if finite else None,
            "ci": {"level": lv_ci, "param": par, "conf": conf},
            "crossing": "inside" if finite else ("below" if xc < 0 else "above"),
            "method": used,
            "why": why,
            "n_episodes": n_eps,
            "n_boot": n_boot,
            "boot_isotonic": n_iso,
            "resampled": _resampled(clusters, cluster_names),
        }
    return out


def _widened(lv_ci: list, x: np.ndarray, xc: float, fixed: bool) -> list:
    """Rates of 0 and 1 (``fixed``: separated, or not monotone like 0/5, 5/5, 0/5) give the episode bootstrap
    nothing to vary: the data only place the crossing between the two adjacent levels around it, so the interval
    covers at least that bracket (else a 95 % interval of zero width)."""
    if not (fixed and math.isfinite(xc)):
        return lv_ci
    i = max(int(np.searchsorted(x, xc, side="right")) - 1, 0)
    j = min(i + 1, len(x) - 1)
    lo, hi = lv_ci
    return [
        float(min(lo, x[i])) if lo is not None else None,
        float(max(hi, x[j])) if hi is not None else None,
    ]


def _resampled(clusters: list[tuple], names: Sequence[str] = ()) -> str:
    depth = len(clusters[0]) if clusters else 0
    label = [names[i] if i < len(names) else f"cluster key {i}" for i in range(depth)]
    stages = [label[i] for i in range(depth) if len({c[i] for c in clusters}) > 1]
    return " → ".join([*stages, "episodes within levels"])


def break_point_difference(
    cells_a: Sequence[Cell],
    cells_b: Sequence[Cell],
    gamma: float = 0.2,
    *,
    n_boot: int = 1000,
    conf: float = 0.95,
    seed: int = 0,
) -> dict:
    """Break point of run B minus run A per direction, with a CI from independent bootstraps of each run."""
    rng = np.random.default_rng(seed)
    signed = any(c.level < 0 for c in [*cells_a, *cells_b])
    out = {}
    for direction in ("pos", "neg") if signed else ("pos",):
        ra = _boot_crossings(cells_a, direction, gamma, "auto", n_boot, rng)
        rb = _boot_crossings(cells_b, direction, gamma, "auto", n_boot, rng)
        sign, x, params = ra[0], ra[1], ra[2]
        with np.errstate(invalid="ignore"):
            diff = rb[7] - ra[7]
        point = rb[4] - ra[4] if math.isfinite(ra[4]) and math.isfinite(rb[4]) else None
        pa = [_to_param(v, x, params) for v in ra[7]]
        pb = [_to_param(v, rb[1], rb[2]) for v in rb[7]]
        with np.errstate(invalid="ignore"):
            dparam = np.array(pb) - np.array(pa)
        lv, dpar = _interval(diff, conf), _interval(dparam, conf)
        own_a, own_b = _interval(ra[7], conf), _interval(rb[7], conf)
        ia = _widened(own_a, x, ra[4], "separated" in ra[6] or ra[10])
        ib = _widened(own_b, rb[1], rb[4], "separated" in rb[6] or rb[10])
        if ia != own_a or ib != own_b:  # a run the bootstrap cannot vary
            lv, dpar = _difference_bracket(lv, dpar, ia, ib, (x, params), (rb[1], rb[2]))
        if sign < 0:
            lv = [-v if v is not None else None for v in lv[::-1]]
        pt_param = None
        if point is not None:
            pt_param = _to_param(rb[4], rb[1], rb[2]) - _to_param(ra[4], x, params)
        out[direction] = {
            "level": sign * point if point is not None else None,
            "param": pt_param,
            "ci": {"level": lv, "param": dpar, "conf": conf},
            "methods": [ra[5], rb[5]],
            "n_boot": n_boot,
            "undefined_replicates": int(np.isnan(diff).sum()),
            "bootstrap": "independent per run",
        }
    return out


def _difference_bracket(lv: list, dpar: list, ia: list, ib: list, xa: tuple, xb: tuple) -> tuple[list, list]:
    """The difference's interval widened to cover B's interval minus A's (each widened to its bracket): when a run's
    bootstrap cannot vary, the replicates' differences alone would give an interval of zero width."""
    if None in (*lv, *ia, *ib):
        return lv, dpar
    lo, hi = min(lv[0], ib[0] - ia[1]), max(lv[1], ib[1] - ia[0])
    ends = [_to_param(b, *xb) - _to_param(a, *xa) for a in ia for b in ib]
    par = dpar if None in dpar else [min(dpar[0], *ends), max(dpar[1], *ends)]
    return [float(lo), float(hi)], [float(v) for v in par]
