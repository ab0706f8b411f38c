"""Held-out certification: every attempt on a level draws its episodes from a seed block that no earlier attempt,
replay, sweep or tuning run used, and the rule spends its 5 % error over the attempts (Bonferroni), so a level
re-tried until it passes is not certified by the retrying. scenes/certification/README.md, "Held-out attempts".

A *seed block* b is the set of initial states ``episode_seed(b, scene, task, axis, level, i)``, i = 0, 1, ...;
block 0 (``LEGACY_BLOCK``) is what every certificate made before this rule, the oracle sweeps
(``scripts/sweep_libero_oracle.py``) and their debugging replays used, so it is burnt for every level and never
certifies anything again. Attempt j (j = 1, 2, ... counting the level's held-out attempts that could certify)
certifies when the one-sided Clopper–Pearson lower bound at confidence 1 - ``attempt_alpha(j)`` is >= 0.95:
attempt 1 spends 0.0485 (59/59, as before), every later one half of what is left of 0.05 (141/141, 154/154, ...),
so the chance that any attempt certifies a level whose oracle rate is below 0.95 stays below 5 % however many
attempts are made (``false_certification``, computed by exact binomial enumeration).
"""

from __future__ import annotations

from scipy.stats import binom

from indgen_vla.core.errors import ConfigError
from scenes.certificates import episodes_needed, lower_bound, row_oracle_version

ALPHA = 0.05  # the error the rule spends over every attempt on a level
FIRST_ALPHA = 0.0485  # attempt 1: 59/59 certifies (0.95**59 = 0.04849 <= 0.0485)
LEGACY_BLOCK = 0  # the certificates before this rule, the sweeps and their replays: burnt everywhere
MAX_ATTEMPTS = 30  # attempt 30 needs 519/519; past ~50, 1 - alpha_j is 1.0 in floating point
FIRST_BLOCK = 1  # the first block a held-out attempt may draw
RULE = "clopper-pearson-sequential-held-out"  # a certificate's rule name under this scheme
SPENDING = (
    "attempt 1 at alpha 0.0485 (59/59), attempt j > 1 at 0.0015 / 2**(j-1); one never-used seed block each"
)
HELD_OUT = "held-out"
IN_SAMPLE = "in-sample (tuned)"
EXHAUSTIVE = "exhaustive"  # a family with a finite set of initial states (LIBERO: 50), every one solved
LABELS = {HELD_OUT: "certified on held-out states", IN_SAMPLE: "certified in-sample (tuned)",
          EXHAUSTIVE: "certified on every fixed initial state"}  # fmt: skip


def attempt_alpha(j: int) -> float:
    """The error attempt ``j`` (1-based) may spend: 0.0485, then halving what is left of 0.05 (sum < 0.05)."""
    if j < 1:
        raise ConfigError(f"attempts are numbered from 1, got {j}")
    if j > MAX_ATTEMPTS:  # 1 - alpha_j would round to 1.0 soon after: no episode count could certify
        raise ConfigError(f"a level gets at most {MAX_ATTEMPTS} held-out attempts (this would be attempt {j}); "
                         "record it as failed")  # fmt: skip
    return FIRST_ALPHA if j == 1 else (ALPHA - FIRST_ALPHA) / 2 ** (j - 1)


def attempt_confidence(j: int) -> float:
    """The one-sided confidence of attempt ``j``'s Clopper–Pearson bound."""
    return 1.0 - attempt_alpha(j)


def certifying_count(n: int, confidence: float, threshold: float) -> int | None:
    """The fewest successes of ``n`` whose lower bound reaches ``threshold`` (None when not even n/n does)."""
    if lower_bound(n, n, confidence) < threshold:
        return None
    lo, hi = 0, n
    while lo < hi:  # the bound rises with the successes
        mid = (lo + hi) // 2
        if lower_bound(mid, n, confidence) >= threshold:
            hi = mid
        else:
            lo = mid + 1
    return lo


def attempt_pass_probability(p: float, n: int, confidence: float, threshold: float) -> float:
    """P(an attempt of at most ``n`` episodes certifies | oracle rate p): the sequential rule stops early only on
    futility and certifies only at n, so this is P(Binomial(n, p) >= the certifying count)."""
    x = certifying_count(n, confidence, threshold)
    return 0.0 if x is None else float(binom.sf(x - 1, n, p))


def false_certification(p: float, attempts: int, threshold: float = 0.95, n_max: int | None = None) -> float:
    """P(some of ``attempts`` held-out attempts certifies | oracle rate p), attempt j at ``attempt_confidence(j)``
    on its own block (independent), each of ``n_max`` episodes or the fewest that can certify."""
    miss = 1.0
    for j in range(1, attempts + 1):
        conf = attempt_confidence(j)
        n = n_max or episodes_needed(threshold, conf)
        miss *= 1.0 - attempt_pass_probability(p, n, conf, threshold)
    return 1.0 - miss


def naive_false_certification(p: float, attempts: int, threshold: float = 0.95) -> float:
    """The same with every attempt at the old fixed 95 % (59/59): keeping the best of several versions."""
    one = attempt_pass_probability(p, episodes_needed(threshold, 0.95), 0.95, threshold)
    return 1.0 - (1.0 - one) ** attempts


# ---- a level's ledger: its attempts and burnt blocks (certify.json rows) ----


def ledger(row: dict, cert: dict | None = None) -> list[dict]:
    """A row's attempts; a row made before they were recorded gets one, conservatively: a held-out attempt 1 on
    block 0 that spent its share (the level's first run could have failed before this one), history unknown."""
    if "attempts" in row:
        return list(row["attempts"])

    version = row_oracle_version(row, cert)
    return [{"attempt": 1, "block": LEGACY_BLOCK, "held_out": True, "alpha": FIRST_ALPHA, "n": row["n"],
             "successes": row["successes"], "status": row.get("status", "insufficient"),
             "oracle": {"version": version}, "history": "unknown (made before attempts were recorded)"}]  # fmt: skip


def spent_attempts(row: dict | None) -> int:
    """How many of the level's attempts were held-out and could certify (each spent its ``alpha``)."""
    return sum(1 for a in (row or {}).get("attempts", ()) if a.get("held_out") and a.get("alpha", 0) > 0)


def used_blocks(row: dict | None, burnt: list | None = None) -> set[int]:
    """Every block a level's episodes came from or a replay/sweep looked at (block 0 always)."""
    used = {LEGACY_BLOCK}
    used |= {int(a["block"]) for a in (row or {}).get("attempts", ()) if a.get("block") is not None}
    if row and row.get("block") is not None:
        used.add(int(row["block"]))
    used |= {int(b["block"] if isinstance(b, dict) else b) for b in burnt or ()}
    return used


def next_block(row: dict | None, burnt: list | None = None, first: int = FIRST_BLOCK) -> int:
    """The smallest block >= ``first`` the level has never used."""
    used, b = used_blocks(row, burnt), max(first, FIRST_BLOCK)
    while b in used:
        b += 1
    return b


def basis(row: dict | None) -> str:
    """How a certified row was made: ``HELD_OUT``, ``EXHAUSTIVE`` or ``IN_SAMPLE`` (a row without a recorded
    basis, e.g. a certificate made before this rule on the user's machine, has an unknown history: in-sample)."""
    made = (row or {}).get("certified_on")
    return made if made in (HELD_OUT, EXHAUSTIVE) else IN_SAMPLE


def covers_every_state(row: dict, states: int) -> bool:
    """Did the row's last attempt play every one of a family's ``states`` fixed initial states (episode i starts
    from state i % states; unavailable ones count as played: the placement check ruled them out of the level)?"""
    return states > 0 and int(row["n"]) + int(row.get("unavailable", 0)) >= states


def fixed_states_basis(row: dict, states: int) -> dict:
    """``row`` of a family with ``states`` fixed initial states (LIBERO): a seed block repeats them (episode i is
    state i % states whatever the block, and the simulation is deterministic), so no attempt is held-out and none
    spends error; a certified row that played every state is ``EXHAUSTIVE`` (the oracle solves each state the
    level holds: no sampling error, and exactly the states ``evaluate`` runs), else ``IN_SAMPLE``."""
    out = {**row, "attempts": [{**a, "held_out": False, "alpha": 0.0, "attempt": None,
                                "fixed_states": f"{states}: every seed block repeats them"}
                               for a in row.get("attempts", ())]}  # fmt: skip
    out.pop("certified_on", None)
    if row.get("status") == "certified":
        out["certified_on"] = EXHAUSTIVE if covers_every_state(row, states) else IN_SAMPLE
    return out


def burnt_blocks(cert: dict, level: int) -> list:
    """The blocks recorded as looked at outside an attempt (a debugging replay, a sweep) for ``level``."""
    return list((cert.get("burnt") or {}).get(str(int(level)), ()))


def burn_block(cert: dict, level: int, block: int, why: str) -> dict:
    """Record that ``block``'s episodes of ``level`` were looked at (a replay, a sweep): no attempt draws it."""
    burnt = cert.setdefault("burnt", {}).setdefault(str(int(level)), [])
    if int(block) not in {int(b["block"]) for b in burnt}:
        burnt.append({"block": int(block), "why": why})
    return cert
