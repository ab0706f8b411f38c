"""LIBERO's task registry and BDDL problems, read and edited as text (no ``libero`` import, no simulator).

A level's BDDL is LIBERO's file with the pick object's and the receptacle's init regions moved and, for the
distractor axis, extra fixtures declared; everything else (language, goal, other objects) is untouched.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from indgen_vla.core.errors import SceneError
from scenes.libero.assets import libero_root

_REGION = re.compile(r"\(\s*([A-Za-z0-9_]+)\s*\(:target\s+([A-Za-z0-9_]+)\)\s*\(:ranges\s*\(\s*\(([^()]*)\)")


@cache
def suite_task_names(suite: str) -> tuple[str, ...]:
    """LIBERO's task files of ``suite`` in benchmark order (lerobot's task_id i is entry i)."""
    path = libero_root() / "benchmark" / "libero_suite_task_map.py"
    try:
        tree = ast.parse(path.read_text())
        node = next(
            n.value
            for n in tree.body
            if isinstance(n, ast.Assign) and any(getattr(t, "id", "") == "libero_task_map" for t in n.targets)
        )
        return tuple(ast.literal_eval(node)[suite])
    except (OSError, StopIteration, KeyError, ValueError, SyntaxError):
        raise SceneError(
            f"cannot read LIBERO's task list for {suite} from {path}; reinstall hf-libero"
        ) from None


def short_name(pattern: str, task_file: str) -> str:
    """The task's short name: group 1 of the suite's ``task_pattern`` (``scenes.libero.LiberoSuite``)."""
    m = re.fullmatch(pattern, task_file)
    return m.group(1) if m else task_file


def language(task_file: str) -> str:
    """The instruction exactly as LIBERO's benchmark (and lerobot) derive it from the file name."""
    return " ".join(task_file.split("_"))


@dataclass(frozen=True)
class LiberoTask:
    """One LIBERO task: where its BDDL and fixed initial states are and which objects the goal names."""

    suite: str
    task_id: int
    file: str  # LIBERO's task name (BDDL/init file stem)
    short: str
    language: str
    objects: tuple[tuple[str, str], ...]  # (instance, category)
    pick: str  # instance moved by the goal predicate, e.g. alphabet_soup_1
    goal: str  # receptacle instance, e.g. basket_1
    pick_region: str  # the table region under the pick object (under what it rests on, if not the table)
    goal_region: str
    regions: tuple[tuple[str, tuple[float, float, float, float]], ...]
    pick_on_table: bool = True  # False when the pick starts on another object or inside a fixture (a drawer)

    def __post_init__(self) -> None:
        names = dict(self.objects)
        if self.pick not in names or self.goal not in names:
            raise SceneError(
                f"LIBERO task {self.file}: goal objects {self.pick}/{self.goal} are not declared"
            )

    @property
    def bddl_path(self) -> Path:
        return libero_root() / "bddl_files" / self.suite / f"{self.file}.bddl"

    @property
    def init_path(self) -> Path:
        return libero_root() / "init_files" / self.suite / f"{self.file}.pruned_init"

    def category(self, instance: str) -> str:
        return dict(self.objects)[instance]

    def centre(self, region: str) -> tuple[float, float]:
        x0, y0, x1, y1 = dict(self.regions)[region]
        return (round((x0 + x1) / 2, 9), round((y0 + y1) / 2, 9))


def parse_regions(text: str) -> dict[str, tuple[str, tuple[float, float, float, float]]]:
    """``name -> (target, (x0, y0, x1, y1))`` for every region with explicit ranges."""
    out = {}
    for name, target, ranges in _REGION.findall(text):
        vals = tuple(float(v) for v in ranges.split())
        if len(vals) == 4:
            out[name] = (target, vals)
    return out


def _section(text: str, head: str) -> str:
    i = text.find(f"(:{head}")
    if i < 0:
        return ""
    depth = 0
    for j in range(i, len(text)):
        depth += {"(": 1, ")": -1}.get(text[j], 0)
        if depth == 0:
            return text[i : j + 1]
    return text[i:]


@cache
def load_task(suite: str, pattern: str, short: str) -> LiberoTask:
    """Parse the task's BDDL (``pattern``: the suite's ``task_pattern``): objects, init regions and the (In/On pick
    receptacle) goal."""
    files = suite_task_names(suite)
    by_short = {short_name(pattern, f): (i, f) for i, f in enumerate(files)}
    task_id, file = by_short[short]
    path = libero_root() / "bddl_files" / suite / f"{file}.bddl"
    try:
        text = path.read_text()
    except OSError:
        raise SceneError(f"LIBERO's BDDL file {path} is missing; reinstall hf-libero") from None
    objects = _declared(_section(text, "objects"))
    instances = sorted((i for i, _ in objects + _declared(_section(text, "fixtures"))), key=len, reverse=True)
    on = dict(re.findall(r"\((?:On|In)\s+([A-Za-z0-9_]+)\s+([A-Za-z0-9_]+)\)", _section(text, "init")))
    m = re.search(r"\((?:In|On)\s+([A-Za-z0-9_]+)\s+([A-Za-z0-9_]+)\)", _section(text, "goal"))
    if not m:
        raise SceneError(f"LIBERO task {file}: no (In/On pick receptacle) goal in {path}")
    pick, target = m.groups()
    goal = target.removesuffix("_contain_region")
    regions = parse_regions(text)

    def region_of(inst: str, seen: tuple[str, ...] = ()) -> str:
        """The table region under ``inst``, following what it rests on / sits in (cookie box, drawer)."""
        ref = on.get(inst, "")
        for name, (tgt, _) in regions.items():
            if ref == f"{tgt}_{name}":
                return name
        holder = next((i for i in instances if ref == i or ref.startswith(i + "_")), None)
        if holder is None or holder in seen:
            raise SceneError(f"LIBERO task {file}: {inst} is not placed on a floor/table region or object")
        return region_of(holder, (*seen, inst))

    pick_region = region_of(pick)
    on_table = on.get(pick) == f"{regions[pick_region][0]}_{pick_region}"
    return LiberoTask(
        suite,
        task_id,
        file,
        short,
        language(file),
        objects,
        pick,
        goal,
        pick_region,
        region_of(goal),
        tuple((k, v[1]) for k, v in regions.items()),
        on_table,
    )


def _declared(section: str) -> tuple[tuple[str, str], ...]:
    """``(instance, category)`` pairs of a BDDL ``(:objects ...)``/``(:fixtures ...)`` section."""
    out = []
    for line in section.splitlines():
        names, sep, category = line.partition(" - ")
        if sep:
            out += [(n, category.strip().rstrip(")").strip()) for n in names.split() if not n.startswith("(")]
    return tuple(out)


def shift_region(text: str, region: str, dx: float, dy: float) -> str:
    """The BDDL with one region's ranges translated by (dx, dy)."""

    def repl(m: re.Match) -> str:
        if m.group(1) != region:
            return m.group(0)
        x0, y0, x1, y1 = (float(v) for v in m.group(3).split())
        new = f"{x0 + dx:.6f} {y0 + dy:.6f} {x1 + dx:.6f} {y1 + dy:.6f}"
        return m.group(0)[: m.start(3) - m.start(0)] + new + m.group(0)[m.end(3) - m.start(0) :]

    out, n = _REGION.subn(repl, text)
    if n == 0 or out == text and (dx or dy):
        raise SceneError(f"BDDL region {region!r} not found")
    return out


def add_fixtures(text: str, fixtures: list[tuple[str, str]]) -> str:
    """The BDDL with extra ``instance - category`` fixtures declared (distractors; no init placement)."""
    sec = _section(text, "fixtures")
    if not sec or not fixtures:
        return text
    extra = "".join(f"    {inst} - {cat}\n" for inst, cat in fixtures)
    return text.replace(sec, sec[:-1].rstrip() + "\n" + extra + "  )", 1)
