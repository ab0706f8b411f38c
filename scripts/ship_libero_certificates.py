"""Copy LIBERO certificates made on the complete tree into scenes/certification/ (keyed by its listing) and
regenerate SUMMARY.md.

    python scripts/ship_libero_certificates.py SRC [--how TEXT]

SRC holds ``libero_object/<task>/<axis>/certify.json`` as ``certify_many(..., root=SRC)`` writes them. Each must
have been made on a tree whose files LIBERO-Object loads are those of the tree ``indgen setup libero`` installs;
the machine's path is dropped, the listing of that tree recorded, and what it was made on kept as ``made_on``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv=None) -> int:
    from indgen_vla.app.certify.suite import write_summary
    from indgen_vla.core.resources import certification_dir
    from scenes.family import get_scene
    from scenes.heldout import fixed_states_basis
    from scenes.libero.install import COMPLETE_TREE, FILES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", help="a certify_many root holding libero_object/<task>/<axis>/certify.json")
    ap.add_argument("--how", default="the tree 'indgen setup libero' installs", help="how the episodes ran")
    a = ap.parse_args(argv)
    dst = certification_dir()
    for p in sorted(Path(a.src).glob("libero_*/*/*/certify.json")):
        c = json.loads(p.read_text())
        made = c.pop("assets", None) or {}
        c["assets"] = {
            "root": "the tree 'indgen setup libero' installs",
            "files": FILES,
            "listing_sha256": COMPLETE_TREE,
        }
        if made.get("listing_sha256") != COMPLETE_TREE:
            c["made_on"] = {
                "listing_sha256": made.get("listing_sha256"),
                "files": made.get("files"),
                "how": a.how,
            }
        c.pop("shipped_assets", None)
        states = get_scene(
            c["scene"]
        ).fixed_state_count  # blocks repeat LIBERO's fixed states (scenes.heldout)
        c["levels"] = [
            fixed_states_basis(r, states) if states and "attempts" in r else r for r in c["levels"]
        ]
        out = dst / p.relative_to(a.src)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(c, indent=1) + "\n")
        print(out)
    print(write_summary(dst))
    return 0


if __name__ == "__main__":
    sys.exit(main())
