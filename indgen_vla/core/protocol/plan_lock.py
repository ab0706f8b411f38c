"""A pre-registered design: ``indgen budget --write plan.lock`` stores the protocol (the plan a resume matches, the
episodes' hash, the fingerprint fields that change outcomes and are known before a policy loads), the stopping
rule, γ/δ/α, the episode budget and the analysis to report; ``evaluate --preregistered`` refuses any deviation in
one line and ``report``/``compare`` say "locked, hash H" or list the deviations (docs/budget.md).

The hash proves that the run followed the lock, not that the lock came first: anyone can write a lock after a run.
It shows pre-registration only where it was published (or signed or timestamped by something the user controls)
before the run; ``report --lock-published WHERE`` prints where, and without it the line says it is not shown."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError

LOCK_VERSION = 1
# fingerprint fields that change outcomes and are fixed before the policy loads (cameras, image size, the render
# backend and the policy's conventions are checked by the run's own fingerprint on a resume)
LOCKED_FINGERPRINT = ("scene", "family", "simulator", "assets", "horizon", "settle_steps", "initial_states")


def _canonical(body: Mapping[str, Any]) -> bytes:
    return json.dumps(body, sort_keys=True, separators=(",", ":"), default=str).encode()


def lock_hash(body: Mapping[str, Any]) -> str:
    """sha256 of the lock's content without its own ``hash`` field (canonical JSON)."""
    return hashlib.sha256(_canonical({k: v for k, v in body.items() if k != "hash"})).hexdigest()


def make_lock(plan: Mapping[str, Any], jobs_sha256: str, fingerprint: Mapping[str, Any], analysis: Mapping[str, Any],
              budget: Mapping[str, Any]) -> dict[str, Any]:  # fmt: skip
    """The lock's content: what ``evaluate`` must run and what ``report``/``compare`` must report."""
    adaptive = plan.get("adaptive")
    body = {
        "lock_version": LOCK_VERSION,
        "plan": json.loads(json.dumps(dict(plan), default=str)),
        "jobs_sha256": jobs_sha256,
        "fingerprint": {k: fingerprint.get(k) for k in LOCKED_FINGERPRINT},
        "stopping": adaptive["mode"] if adaptive else "fixed",
        "analysis": dict(analysis),
        "budget": dict(budget),
    }
    return {**body, "hash": lock_hash(body)}


def read_lock(path: str | Path) -> dict[str, Any]:
    """A lock file, its hash checked (an edited lock is refused in one line)."""
    p = Path(path)
    try:
        lock = json.loads(p.read_text())
    except FileNotFoundError:
        raise ConfigError(
            f"--preregistered {p}: no such file; write one with 'indgen budget ... --write {p}'"
        ) from None
    except (OSError, ValueError) as e:
        raise ConfigError(f"--preregistered {p}: not a lock file ({e.__class__.__name__}); write it again with "
                          "'indgen budget --write'") from None  # fmt: skip
    if not isinstance(lock, dict) or lock.get("lock_version") != LOCK_VERSION or "hash" not in lock:
        raise ConfigError(
            f"--preregistered {p}: not a version-{LOCK_VERSION} lock; write it again with 'indgen budget --write'"
        )
    if lock_hash(lock) != lock["hash"]:
        raise ConfigError(f"--preregistered {p}: its content does not match its hash (edited after it was written); "
                          "write a new lock with 'indgen budget --write'")  # fmt: skip
    return lock


def _diff(prefix: str, locked: Any, now: Any, out: list[str]) -> None:
    if isinstance(locked, Mapping) and isinstance(now, Mapping):
        for k in sorted(set(locked) | set(now), key=str):
            _diff(f"{prefix}.{k}" if prefix else str(k), locked.get(k), now.get(k), out)
    elif json.dumps(locked, sort_keys=True, default=str) != json.dumps(now, sort_keys=True, default=str):
        out.append(f"{prefix} is {json.dumps(now, default=str)}, locked {json.dumps(locked, default=str)}")


def protocol_deviations(lock: Mapping[str, Any], plan: Mapping[str, Any], jobs_sha256: str | None,
                        fingerprint: Mapping[str, Any] | None) -> list[str]:  # fmt: skip
    """What a run's protocol does differently from the lock, one phrase each (empty: none)."""
    out: list[str] = []
    _diff("", lock["plan"], json.loads(json.dumps(dict(plan), default=str)), out)
    if jobs_sha256 is not None and jobs_sha256 != lock["jobs_sha256"]:
        out.append("the planned episodes (their seeds and parameters) differ from the locked ones")
    if fingerprint is not None:
        _diff("fingerprint", lock["fingerprint"], {k: fingerprint.get(k) for k in LOCKED_FINGERPRINT}, out)
    return out


def analysis_deviations(lock: Mapping[str, Any], **analysis: Any) -> list[str]:
    """The analysis asked now (report's γ and interval, compare's α and test) against the locked one; only the
    keys given are compared."""
    out: list[str] = []
    for k, v in analysis.items():
        if k in lock["analysis"] and lock["analysis"][k] != v:
            out.append(f"{k} is {v}, locked {lock['analysis'][k]}")
    return out


def run_deviations(manifest: Mapping[str, Any], planned: int, recorded: int) -> list[str] | None:
    """None for a run made without ``--preregistered``; else its deviations from its lock (the lock the manifest
    holds): protocol changes a resume went on despite, and a budget left unspent."""
    reg = manifest.get("preregistered")
    if not reg:
        return None
    lock = reg["lock"]
    out = protocol_deviations(lock, manifest.get("plan", {}), (manifest.get("resolved") or {}).get("jobs_sha256"),
                              manifest.get("fingerprint"))  # fmt: skip
    out += [f"resumed under another protocol: {c.get('field')}" for c in manifest.get("protocol_changes", [])]
    if lock["stopping"] == "fixed" and recorded < planned:
        out.append(f"stopped early: {recorded} of {planned} planned episodes recorded")
    return out


UNPUBLISHED = ("not shown to precede the run: a lock's hash proves that only where it was published before the run "
               "(report --lock-published WHERE)")  # fmt: skip


def status_line(
    manifest: Mapping[str, Any], deviations: list[str] | None, published: str | None = None
) -> str | None:
    """ "locked, hash H, followed; published WHERE" or the deviations, for report and compare; None without a lock."""
    if deviations is None:
        return None
    short = manifest["preregistered"]["hash"][:12]
    where = f"published {published}" if published else UNPUBLISHED
    if not deviations:
        return f"locked, hash {short}, followed; {where}"
    return (
        f"locked, hash {short}, with {len(deviations)} deviation(s): " + "; ".join(deviations) + f"; {where}"
    )


def run_status(
    manifest: Mapping[str, Any], recorded: int, published: str | None = None, **analysis: Any
) -> str | None:
    """``report``/``compare``'s line for one run: "locked, hash H, followed (where it was published)", its deviations
    (the run's, and the analysis asked now against the locked one), or None for a run made without a lock."""
    plan = manifest.get("plan", {})
    planned = (
        len(plan.get("tasks", []))
        * sum(len(v) for v in plan.get("levels", {}).values())
        * int(plan.get("episodes", 0))
    )
    found = run_deviations(manifest, planned, recorded)
    if found is None:
        return None
    return status_line(
        manifest, found + analysis_deviations(manifest["preregistered"]["lock"], **analysis), published
    )
