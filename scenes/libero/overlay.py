"""Run on a partial LIBERO asset tree (a GitHub mirror that lacks its largest blobs): a symlink copy of the tree
with a tiny placeholder for every file its MJCF references but that is missing, and the list of what was filled.

For physics checks only (the oracle, certification, the ``real_assets`` tests, timing): a filled visual mesh or
texture changes what a camera sees, so such a tree is marked (``assets.PLACEHOLDER_MARK``) and
``evaluate`` refuses an image policy on it unless ``--smoke``. ``collision`` in the
report names any filled file that a collision geom could use (those change the physics too).

    indgen setup libero --overlay SRC --dest DST     # then: export INDGEN_LIBERO_ASSETS=DST
"""

from __future__ import annotations

import io
import os
import re
import struct
from pathlib import Path

from scenes.libero.assets import mark_placeholder

_FILE_REF = re.compile(r'file="([^"]+)"')
_COMMENT = re.compile(r"<!--.*?-->", re.S)


def referenced_missing(assets: Path) -> list[Path]:
    """Files that the tree's own MJCF files reference (relative paths inside the tree, outside comments) but
    that are absent."""
    assets = Path(assets)
    root = assets.resolve()
    missing = set()
    for xml in assets.rglob("*.xml"):
        for ref in _FILE_REF.findall(_COMMENT.sub("", xml.read_text(errors="ignore"))):
            if os.path.isabs(ref):
                continue
            p = Path(os.path.normpath(xml.parent / ref))
            if not p.exists() and root in p.resolve().parents:
                missing.add(p)
    return sorted(missing)


def placeholder_bytes(suffix: str) -> bytes:
    """A tiny stand-in for a missing file: a 1 cm tetrahedron (.msh / .stl / .obj) or a 4×4 grey PNG."""
    v = [(0, 0, 0), (0.01, 0, 0), (0, 0.01, 0), (0, 0, 0.01)]
    f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    if suffix == ".msh":  # MuJoCo's legacy binary mesh: nvert, nnormal, ntexcoord, nface, then the arrays
        return (
            struct.pack("4i", 4, 0, 0, 4) + struct.pack("12f", *sum(v, ())) + struct.pack("12i", *sum(f, ()))
        )
    if suffix == ".stl":
        tris = b"".join(struct.pack("<12fH", 0, 0, 0, *v[a], *v[b], *v[c], 0) for a, b, c in f)
        return b"\0" * 80 + struct.pack("<I", len(f)) + tris
    if suffix == ".obj":
        return ("".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(
            f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)).encode()  # fmt: skip
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (128, 128, 128)).save(buf, format="PNG")  # MuJoCo reads PNG by content
    return buf.getvalue()


def overlay_assets(src: Path, dst: Path) -> list[str]:
    """A symlink copy of ``src`` at ``dst`` with a placeholder for each referenced-but-missing file; their paths
    relative to ``src``. Re-running on the same ``dst`` keeps what is there."""
    src, dst = Path(src).resolve(), Path(dst)
    missing = referenced_missing(src)
    for dirpath, _, files in os.walk(src):
        out = dst / Path(dirpath).relative_to(src)
        out.mkdir(parents=True, exist_ok=True)
        for name in files:
            if not (out / name).exists():
                (out / name).symlink_to(Path(dirpath, name).resolve())
    for p in missing:
        q = dst / p.relative_to(src)
        q.parent.mkdir(parents=True, exist_ok=True)
        q.write_bytes(placeholder_bytes(q.suffix.lower()))
    if missing:  # a filled mesh or texture changes what a camera sees
        mark_placeholder(
            dst, f"An overlay of {src} (scenes.libero.overlay) with {len(missing)} missing file(s) filled."
        )
    return [str(p.relative_to(src)) for p in missing]


def collision_suspects(filled: list[str]) -> list[str]:
    """Filled meshes that are not named as visual-only (LIBERO keeps visuals in ``visual/`` or ``*_vis.*``)."""
    meshes = [p for p in filled if Path(p).suffix.lower() in (".msh", ".stl", ".obj")]
    return [p for p in meshes if "/visual/" not in f"/{p}" and "_vis." not in Path(p).name]


# a command moved into `indgen setup`: say so, never exit 0 having written nothing
if __name__ == "__main__":
    raise SystemExit(
        "error: 'python -m scenes.libero.overlay' was moved; run 'indgen setup libero --overlay SRC --dest DST'"
    )
