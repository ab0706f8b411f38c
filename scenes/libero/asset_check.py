"""Which files LIBERO's own code loads from an asset tree, and which of them a tree lacks.

hf-libero builds a task from its BDDL problem: the problem class loads a scene XML (``scenes/*.xml``, named in
``libero/libero/envs/problems/``), and every object and fixture the BDDL declares is an object class of LIBERO's
registry (``OBJECTS_DICT``) that loads its own XML. Those XMLs name the meshes and textures they need. A tree that
lacks one of these files fails at build time, whatever suite or level; ``missing_references`` lists them up front.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from scenes.libero.assets import import_libero, libero_root

_SCENE_XML = re.compile(r"[\"'](scenes/[\w./-]+\.xml)[\"']")
_DECLARED = re.compile(r"\(:(objects|fixtures)(.*?)\)", re.S)


def bddl_categories(libero_pkg: Path) -> set[str]:
    """Every object/fixture category declared in hf-libero's BDDL files (``name - category`` lines)."""
    cats: set[str] = set()
    for f in sorted((libero_pkg / "bddl_files").rglob("*.bddl")):
        for _, body in _DECLARED.findall(f.read_text()):
            cats.update(m.strip() for m in re.findall(r"-\s*([\w]+)", body))
    return cats


def scene_xmls(libero_pkg: Path) -> set[str]:
    """The scene XMLs hf-libero's problem classes load (relative to the asset tree)."""
    out: set[str] = set()
    for f in sorted((libero_pkg / "envs" / "problems").glob("*.py")):
        out.update(_SCENE_XML.findall(f.read_text()))
    return out


def object_xmls(root: Path) -> tuple[set[Path], list[str]]:
    """The XML of every registered object class the BDDL files declare, resolved against ``root`` by LIBERO's own
    classes, and the categories whose XML could not be read (named by their XML path under ``root``)."""
    import_libero(root)
    from libero.libero.envs import objects  # noqa: F401  (fills the registry)
    from libero.libero.envs.base_object import OBJECTS_DICT

    found, missing = set(), []
    for cat in sorted(bddl_categories(libero_root())):
        cls = OBJECTS_DICT.get(cat)
        if cls is None:  # an arena fixture (the table, the floor), part of the scene XML
            continue
        try:
            found.add(Path(cls().file))
        except FileNotFoundError as e:
            missing.append(str(Path(e.filename).relative_to(root)) if e.filename else cat)
    return found, missing


def file_references(xml: Path) -> list[Path]:
    """The files one MuJoCo XML names (meshes, textures, includes), as robosuite resolves them: beside the XML."""
    tree = ET.parse(xml).getroot()
    comp = tree.find("compiler")
    dirs = {
        "mesh": comp.get("meshdir", "") if comp is not None else "",
        "texture": comp.get("texturedir", "") if comp is not None else "",
    }
    out = []
    for e in tree.iter():
        f = e.get("file")
        if f is not None:
            plain = xml.parent / f
            out.append(plain if plain.exists() else xml.parent / dirs.get(e.tag, "") / f)
    return out


def missing_references(root: Path) -> list[str]:
    """Files (relative to ``root``) that LIBERO's code loads for any of its BDDL tasks and ``root`` lacks."""
    root = Path(root).resolve()
    xmls, missing = object_xmls(root)
    xmls |= {root / s for s in scene_xmls(libero_root())}
    for x in sorted(xmls):
        if not x.is_file():
            missing.append(str(x.relative_to(root)))
            continue
        missing += [str(p.resolve().relative_to(root)) for p in file_references(x) if not p.exists()]
    return sorted(set(missing))
