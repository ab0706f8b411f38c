"""Certificates that ship for a scene whose levels depend on the user's asset tree (LIBERO's suites).

``scenes/certification/<scene>/<task>/<axis>/certify.json`` of such a scene was made on one asset tree, the one
``indgen setup libero`` installs; it records that tree's ``listing_sha256`` (every file's path and size,
``scenes.libero.assets.tree_identity``). It covers a user's tree only when that tree's listing is the same; a tree
that differs (LIBERO's git checkout without its blobs, the miniature, an overlay, a newer download) is not covered,
and ``evaluate`` says so once and goes on as if there were no certificate (``indgen certify`` makes the user's own).
"""

from __future__ import annotations

import sys
from pathlib import Path

_SAID: set[str] = set()


def shipped_certification(scene: str, path: Path) -> dict | None:
    """The shipped certificate at ``path`` (``cert_path`` under ``certification_dir()``) when it was made on a tree
    listed like the user's; else None (with one line on stderr per scene when it exists but the tree differs)."""
    from scenes.certify_run import asset_stamp, load_certification
    from scenes.registry import get_scene

    if get_scene(scene).committed_certificates:
        return None  # the built-ins' certificates are the committed ones already
    if not path.is_file():
        return None
    cert = load_certification(path)
    stamp = asset_stamp(scene)
    made = (cert.get("assets") or {}).get("listing_sha256")
    if stamp is not None and made and stamp.get("listing_sha256") == made:
        return cert
    if scene not in _SAID:
        _SAID.add(scene)
        have = (stamp or {}).get("listing_sha256", "none")
        print(
            f"note: the shipped {scene} certificates cover the asset tree {str(made)[:12]} ('indgen setup "
            f"libero'); yours ({str(have)[:12]}, {(stamp or {}).get('root')}) differs, so they are not used "
            f"here: run 'indgen certify' on it, or install that tree",
            file=sys.stderr,
        )
    return None
