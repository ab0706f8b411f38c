"""The certificate store: the certification rule and its statistics, where certificates live, how ``evaluate``
finds them (``scenes.planning``), their asset stamps and each level's verdict. ``indgen certify`` writes them
(``indgen_vla.app.certify``).

A level is certified (the paper's Assumption 2, stated statistically) when the one-sided 95 % Clopper–Pearson lower
bound of the oracle's success rate is >= the threshold (0.95: 59/59 episodes); scenes/certification/README.md.

Built-in scenes: ``scenes/certification/<scene>/<task>/<axis>/certify.json`` (committed). LIBERO suites and
RoboCasa365: ``$INDGEN_CACHE/certification/<hash of the asset tree path>/<scene>/<task>/<axis>/certify.json``
(``$INDGEN_CACHE`` defaults to ``~/.cache/indgen``), written by ``indgen certify`` on the user's machine; each
records its tree's ``asset_stamp`` (every file's path, size and mtime), and one whose tree has changed since (or
made before stamps were recorded) is never used: ``find_certification`` ignores it and ``certify`` makes it again.
``$INDGEN_CERT_DIR`` replaces either root. An axis certified at non-default steps gets its own folder
``<axis>@<component>=<step>,...``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import re
import sys
from pathlib import Path

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.resources import certification_dir
from indgen_vla.core.runs.records import atomic_write_json
from indgen_vla.core.stats.metrics import clopper_pearson_ci
from scenes.axes import get_successor, load_preset, successor_steps
from scenes.family import Scene
from scenes.libero.assets import tree_identity
from scenes.oracles import oracle_identity

THRESHOLD = 0.95
CONFIDENCE = 0.95
FEASIBLE_RATE = THRESHOLD  # the old name, kept for readers
RULE_NAME = "clopper-pearson-sequential"


def lower_bound(successes: int, n: int, confidence: float = CONFIDENCE) -> float:
    """One-sided lower confidence bound: the two-sided interval at 2*conf-1 has the same lower end."""
    return 0.0 if n == 0 else clopper_pearson_ci(successes, n, conf=2 * confidence - 1)[0]


def episodes_needed(threshold: float = THRESHOLD, confidence: float = CONFIDENCE) -> int:
    """The smallest n at which n/n successes certify (59 for 0.95 at 95 %)."""
    n = 1
    while lower_bound(n, n, confidence) < threshold:
        n += 1
    return n


@dataclasses.dataclass(frozen=True)
class Rule:
    """The certification rule: run up to ``n_max`` episodes, certify when the CP lower bound >= threshold."""

    threshold: float = THRESHOLD
    confidence: float = CONFIDENCE
    n_max: int = 0  # 0: the smallest n that can certify

    def __post_init__(self) -> None:
        if not 0 < self.threshold < 1:
            raise ConfigError(f"--threshold must be in (0, 1), got {self.threshold}")
        if not 0.5 < self.confidence < 1:
            raise ConfigError(f"the confidence must be in (0.5, 1), got {self.confidence}")
        if self.n_max < 0:
            raise ConfigError(f"--episodes must be >= 1, got {self.n_max}")
        if self.n_max == 0:
            object.__setattr__(self, "n_max", episodes_needed(self.threshold, self.confidence))

    def as_dict(self) -> dict:
        return {
            "name": RULE_NAME,
            "threshold": self.threshold,
            "confidence": self.confidence,
            "n_max": self.n_max,
        }

    def reachable(self, successes: int, n: int) -> bool:
        """Could the level still certify if every remaining episode up to n_max succeeded?"""
        return lower_bound(successes + self.n_max - n, self.n_max, self.confidence) >= self.threshold

    def stop(self, successes: int, n: int) -> bool:
        """Stop at n_max, or early once a failure has made certification unreachable."""
        return n >= self.n_max or (successes < n and not self.reachable(successes, n))

    def status(self, successes: int, n: int) -> str:
        """certified | failed (the oracle failed and the bound cannot be reached) | insufficient evidence."""
        if n >= self.n_max and lower_bound(successes, n, self.confidence) >= self.threshold:
            return "certified"
        if successes < n and not self.reachable(successes, n):
            return "failed"
        return "insufficient"


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON so that ``path`` is always either the old or the new complete file (its folder is made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(path, data)


# RoboCasa's MJCFObject writes <time>_<pid>.xml beside each object model while it builds and then deletes it
# (robocasa/models/objects/objects.py): a run going on, or one killed meanwhile, is no change of the assets
_TRANSIENT = re.compile(r"\d+_\d+_\d+\.xml")


@functools.cache
def tree_stamp(root: str) -> tuple[str, int]:
    """SHA-256 over every file's relative path, size and mtime under ``root``, and the number of files: a file
    replaced or edited in place changes it. Stat only (about 1 s for 32k files); hashing the contents would read RoboCasa's
    gigabytes of meshes on every lookup. Computed once per process."""
    h, n = hashlib.sha256(), 0
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        dirnames.sort()
        for name in sorted(filenames):
            if _TRANSIENT.fullmatch(name):
                continue
            path = os.path.join(dirpath, name)
            st = os.stat(path)
            h.update(f"{os.path.relpath(path, root)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
            n += 1
    return h.hexdigest(), n


def asset_stamp(scene: Scene) -> dict | None:
    """What a per-machine certificate records of the asset tree it was made on (``SceneCertificates.asset_tree``):
    its root and ``tree_stamp``; None for a scene without one (the built-ins, whose certificates are committed)."""
    tree = scene.certificates.asset_tree()
    if tree is None:
        return None

    root = str(Path(tree).resolve())
    digest, files = tree_stamp(root)
    # paths and sizes only: equal on every machine that installed the same tree (shipped LIBERO certificates)
    return {"root": root, "files": files, "stat_sha256": digest, "listing_sha256": tree_identity(Path(root))}


def same_assets(cert: dict, stamp: dict | None) -> bool:
    """Was ``cert`` made on the asset files ``stamp`` describes? (A certificate without a stamp, made before they
    were recorded, matches only a scene without an asset tree.)"""
    made = cert.get("assets") or {}
    return stamp is None or made.get("stat_sha256") == stamp["stat_sha256"]


def load_certification(path: str | Path) -> dict:
    """Read a certify.json (or the directory holding one) and check its shape."""
    p = Path(path)
    if p.is_dir():
        p = p / "certify.json"
    if not p.is_file():
        raise RunDirError(f"no certification at {p}; run 'indgen certify --scene S --axis A' first")
    try:
        cert = json.loads(p.read_text())
    except json.JSONDecodeError as e:
        raise RunDirError(
            f"{p} is not valid JSON ({e.msg} at line {e.lineno}); re-run 'indgen certify'"
        ) from None
    if (
        not isinstance(cert, dict)
        or not {"scene", "axis", "levels"} <= cert.keys()
        or not isinstance(cert["levels"], list)
    ):
        raise RunDirError(f"{p} is not a certification (needs scene, axis, levels); re-run 'indgen certify'")
    for row in cert["levels"]:
        if not isinstance(row, dict) or not {"level", "n", "successes", "rate", "feasible"} <= row.keys():
            raise RunDirError(
                f"{p}: a level row lacks level/n/successes/rate/feasible; re-run 'indgen certify'"
            )
    return cert


def level_status(row: dict) -> str:
    """A row's verdict; rows written before the statistical rule count as failed/insufficient evidence."""
    if "status" in row:
        return str(row["status"])
    return "insufficient" if row["feasible"] else "failed"


# The oracle's version (``scenes.oracles.oracle_identity``): each row records the one that ran it. Feasibility is a
# property of the level, so a level any version certified stays certified; a level an older (or other) version
# failed is re-tried by ``certify`` and reported "failed (oracle vN, current vM)" until then. Rows and certificates
# made before versions were recorded count as version 1.
UNKNOWN_VERSION = 1


def row_oracle_version(row: dict, cert: dict | None = None) -> int:
    """The oracle version that made ``row``: its own, else its certificate's, else ``UNKNOWN_VERSION``."""
    if "oracle_version" in row:
        return int(row["oracle_version"])
    return int(((cert or {}).get("oracle") or {}).get("version", UNKNOWN_VERSION))


def current_oracle_version(scene: Scene) -> int | None:
    """The version of ``scene``'s oracle in this checkout (None for a scene this version no longer knows)."""
    try:
        return oracle_identity(scene)["version"]
    except Exception:
        return None


def stale_failure(row: dict, cert: dict | None, current: int | None) -> bool:
    """A failed row made by another oracle version than ``current``: ``certify`` runs it again."""
    return level_status(row) == "failed" and current is not None and row_oracle_version(row, cert) != current


def level_verdict(row: dict, cert: dict | None, current: int | None) -> str:
    """``level_status``, with "failed (oracle v2, current v3)" for a failure another oracle version made."""
    status = level_status(row)
    if stale_failure(row, cert, current):
        return f"{status} (oracle v{row_oracle_version(row, cert)}, current v{current})"
    return status


def infeasible_levels(cert: dict) -> list[int]:
    """Levels where the oracle failed so that the rule can no longer certify them."""
    return sorted(int(r["level"]) for r in cert["levels"] if level_status(r) == "failed")


def certified_levels(cert: dict) -> list[int]:
    return sorted(int(r["level"]) for r in cert["levels"] if level_status(r) == "certified")


def certification_root(scene: Scene | None = None) -> Path:
    """$INDGEN_CERT_DIR, else the committed certificates (``indgen_vla.core.resources.certification_dir``) for the built-in
    scenes, else a cache folder per asset tree."""
    env = os.environ.get("INDGEN_CERT_DIR")
    if env:
        return Path(env)
    if scene is None or scene.committed_certificates:
        return certification_dir()
    assets, scope = (
        scene.certificates.asset_tree(),
        scene.certificates.scope(),
    )  # scope "": the folder certificates had before it
    where = str(assets.resolve() if assets else "none") + (f"\0{scope}" if scope else "")
    tag = hashlib.sha1(where.encode()).hexdigest()[:12]
    return Path(os.environ.get("INDGEN_CACHE", "~/.cache/indgen")).expanduser() / "certification" / tag


def _steps(
    axis: AxisRef, step: float | None, preset: str | None, scene: Scene | None, task: str | None
) -> dict[str, float]:
    """The component steps of ``axis`` with --step / --axes-preset over ``scene``'s (and ``task``'s) own steps."""
    overrides = load_preset(preset) if preset else None
    if scene is None:
        return successor_steps(get_successor(axis, step, overrides))
    return successor_steps(scene.successor(axis, step, overrides, task))


def axis_dirname(
    axis: str | AxisRef, step: float | None = None, preset: str | None = None, scene: Scene | None = None,
    task: str | None = None,
) -> str:  # fmt: skip
    """``axis`` at the (family's, task's) default steps, else ``axis@comp=step,...`` so other steps never overwrite
    it."""
    ref = AxisRef.parse(axis)
    steps = _steps(ref, step, preset, scene, task)
    if steps == _steps(ref, None, None, scene, task):
        return ref.name
    return ref.name + "@" + ",".join(f"{k}={v:g}" for k, v in steps.items())


def cert_path(
    scene: Scene, task: str | None, axis: str | AxisRef, step: float | None = None, preset: str | None = None,
    root: str | Path | None = None,
) -> Path:  # fmt: skip
    """The certify.json of (scene, task, axis, steps)."""
    task = scene.resolve_task(task)
    base = Path(root) if root is not None else certification_root(scene)
    return base / scene.name / task / axis_dirname(axis, step, preset, scene, task) / "certify.json"


def find_certification(
    scene: Scene, task: str | None, axis: str | AxisRef, step: float | None = None, *, preset: str | None = None,
    root: str | Path | None = None,
) -> dict | None:  # fmt: skip
    """The certificate of (scene, task, axis) made at these component steps, or None if there is none."""
    import json

    axis = AxisRef.parse(axis)
    want = _steps(axis, step, preset, scene, scene.resolve_task(task))

    def same_steps(cert: dict) -> bool:
        have = cert.get("steps") or {axis.name: cert.get("step")}
        return json.dumps(want, sort_keys=True) == json.dumps(
            {k: float(v) for k, v in have.items()}, sort_keys=True
        )

    path = cert_path(scene, task, axis, step, preset, root)
    if path.is_file():
        cert = load_certification(path)
        if same_steps(cert) and same_assets(cert, asset_stamp(scene)):  # a changed tree: certify again
            return cert
    if root is None and not os.environ.get("INDGEN_CERT_DIR"):
        cert = shipped_certification(scene, cert_path(scene, task, axis, step, preset, certification_dir()))
        if cert is not None and same_steps(cert):
            return cert
    return None


# Shipped certificates of a scene whose levels depend on the user's asset tree (LIBERO's suites):
# Certificates that ship for a scene whose levels depend on the user's asset tree (LIBERO's suites).
#
# ``scenes/certification/<scene>/<task>/<axis>/certify.json`` of such a scene was made on one asset tree, the one
# ``indgen setup libero`` installs; it records that tree's ``listing_sha256`` (every file's path and size,
# ``scenes.libero.assets.tree_identity``). It covers a user's tree only when that tree's listing is the same; a tree
# that differs (LIBERO's git checkout without its blobs, the miniature, an overlay, a newer download) is not covered,
# and ``evaluate`` says so once and goes on as if there were no certificate (``indgen certify`` makes the user's own).
_SAID: set[str] = set()


def shipped_certification(scene: Scene, path: Path) -> dict | None:
    """The shipped certificate at ``path`` (``cert_path`` under ``certification_dir()``) when it was made on a tree
    listed like the user's; else None (with one line on stderr per scene when it exists but the tree differs)."""
    if scene.committed_certificates:
        return None  # the built-ins' certificates are the committed ones already
    if not path.is_file():
        return None
    cert = load_certification(path)
    stamp = asset_stamp(scene)
    made = (cert.get("assets") or {}).get("listing_sha256")
    if stamp is not None and made and stamp.get("listing_sha256") == made:
        return cert
    if stamp is not None and scene.name not in _SAID:  # no tree at all: the scene's own error says so, once
        _SAID.add(scene.name)
        print(
            f"note: the shipped {scene.name} certificates cover the asset tree {str(made)[:12]} ('indgen setup "
            f"libero'); yours ({str(stamp.get('listing_sha256'))[:12]}, {stamp.get('root')}) differs, so they are not used "
            f"here: run 'indgen certify' on it, or install that tree",
            file=sys.stderr,
        )
    return None
