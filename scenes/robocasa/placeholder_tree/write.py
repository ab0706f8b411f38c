"""Write (or complete) the placeholder tree: the wheel's assets copied, then a placeholder for every file its fixture
registry, its Python sources, its object categories and its own XML reference that it does not ship."""

from __future__ import annotations

import os
import re
import runpy
import shutil
from pathlib import Path

from . import MARKER, VERSION
from .files import ACCESSORY_HALF, BOX_OBJ, Writer, object_half, object_model
from .fixtures import fixture_model, simple_model
from .model import DEFAULT_SIZE, SIZES


def _strings(value):
    """Every string in a nested YAML value."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list | tuple):
        for v in value:
            yield from _strings(v)


def registry_entries(assets: Path):
    import yaml

    for f in sorted((assets / "fixtures" / "fixture_registry").glob("*.yaml")):
        data = yaml.safe_load(f.read_text()) or {}
        for key, cfg in data.items():
            if isinstance(cfg, dict):
                yield f.stem, key, cfg


def referenced_in_sources(pkg: Path) -> set[str]:
    """Asset paths written as literals in RoboCasa's (and robosuite's kitchen-facing) Python sources."""
    pat = re.compile(r"""["']((?:fixtures|textures|objects|generative_textures|arenas)/[^"'\s{}]+)["']""")
    out: set[str] = set()
    for py in pkg.rglob("*.py"):
        if "scripts" in py.parts or "demos" in py.parts:
            continue
        out.update(pat.findall(py.read_text(errors="ignore")))
    return out


def object_categories() -> dict:
    """RoboCasa's raw OBJ_CATEGORIES (before its ObjCat conversion), read from its source file."""
    import robocasa.models.objects as objs

    ns = runpy.run_path(str(Path(objs.__file__).parent / "kitchen_objects.py"))
    return ns["OBJ_CATEGORIES"]


REGISTRY_FOLDERS = {"objaverse": "objaverse", "aigen": "aigen_objs", "lightwheel": "lightwheel"}


def write_tree(dst: Path) -> dict:
    """Write (or complete) the tree; returns the placeholder files per kind ``written`` now and already
    ``present``, the files copied from the wheel (``package``) and every file in the tree (``total``)."""
    import robocasa

    pkg = Path(robocasa.__file__).parent
    wheel_assets = pkg / "models" / "assets"
    marker = dst / MARKER
    if marker.is_file() and not marker.read_text().startswith(f"version {VERSION}\n"):
        shutil.rmtree(dst)  # a placeholder tree of an older generator: written again, never patched in place
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copytree(wheel_assets, dst, dirs_exist_ok=True)
    w = Writer(dst, wheel_assets)
    categories, registry_of = object_categories(), {f: r for r, f in REGISTRY_FOLDERS.items()}
    for kind, key, cfg in registry_entries(wheel_assets):
        xml = cfg.get("xml")
        if isinstance(xml, str):
            rel = xml if xml.endswith(".xml") else f"{xml}/model.xml"
            if xml.startswith("objects/"):  # objects/<registry folder>/<category>/<model>
                parts = rel.split("/")
                reg, cat = registry_of.get(parts[1], ""), parts[2] if len(parts) > 3 else ""
                body = object_model(key, object_half(categories.get(cat), reg, ACCESSORY_HALF))
            else:
                body = fixture_model(kind, key)
            w.write(rel, body, "fixtures")
            w.texture(str(Path(rel).parent / "tex.png"))
        for v in _strings(cfg):  # nested too: a handle style's handle_config.texture
            if v.endswith((".png", ".jpg")):
                w.texture(v)
    for rel in sorted(referenced_in_sources(pkg)):
        if rel.endswith((".png", ".jpg")):
            w.texture(rel)
        elif rel.endswith(".xml"):
            kind = "handle" if "/handles/" in rel else "panel" if "panel" in rel else "other"
            w.write(rel, simple_model(Path(rel).parent.name, SIZES.get(kind, DEFAULT_SIZE)), "fixtures")
            w.texture(str(Path(rel).parent / "tex.png"))
        elif rel.startswith("fixtures/") and not Path(rel).suffix:
            w.write(f"{rel}/model.xml", simple_model(Path(rel).name, DEFAULT_SIZE), "fixtures")
            w.texture(f"{rel}/tex.png")
    for cat, cfg in categories.items():
        for reg, folder in REGISTRY_FOLDERS.items():
            if reg not in cfg:
                continue
            # an auxiliary object (a lid) lives one folder deeper (kitchen_object_utils.ObjCat); the flag is per
            # registry: without the extra folder its category has no model and sampling draws NaN probabilities
            aux = bool(cfg.get("is_auxiliary_obj") or cfg[reg].get("is_auxiliary_obj"))
            folders = cfg[reg].get("model_folders") or [f"{folder}/{cat}"]
            for fold in folders:
                model = f"objects/{fold}/{cat}_ph" + ("/part" if aux else "") + "/model.xml"
                w.write(model, object_model(cat, object_half(cfg, reg)), "objects")
    # files the wheel's own XML points at (cabinet textures, meshes) that the wheel does not ship
    for xml in list(dst.rglob("*.xml")):
        text = xml.read_text(errors="ignore")
        for ref in re.findall(r'file="([^"]+)"', text):
            target = (xml.parent / ref).resolve()
            if not str(target).startswith(str(dst.resolve())):
                continue
            rel = str(target.relative_to(dst.resolve()))  # the writer skips the wheel's own files
            if ref.endswith((".png", ".jpg")):
                w.texture(rel)
            elif ref.endswith((".obj", ".stl", ".msh")):
                w.write(rel, BOX_OBJ, "meshes")
    (dst / MARKER).write_text(f"version {VERSION}\nrobocasa {getattr(robocasa, '__version__', '?')}\n")
    for root, dirs, files in os.walk(dst):  # writable: objects write temporary XML into their folders
        for n in dirs + files:
            p = os.path.join(root, n)
            os.chmod(p, os.stat(p).st_mode | 0o200)
    package = sum(len(files) for _, _, files in os.walk(wheel_assets))
    total = sum(len(files) for _, _, files in os.walk(dst))
    return {"written": w.written, "present": w.present, "package": package, "total": total}
