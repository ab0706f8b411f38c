"""First-party imports inside functions (issue 55 item 4): at most 10 % of all, each with its reason, so that the
layers contract and a reader see the import graph at the top of each module.

A first-party import is an ``import``/``from ... import`` of ``indgen_vla``, ``scenes`` or ``policy_wrappers`` (or a
relative one); it is lazy when its statement sits inside a function body (the AST: nested in a ``FunctionDef``).
Each lazy one carries its reason on its line or on a comment line just above it, in one of three forms:

    # lazy: start-up        a measured start-up cost (``indgen --help`` must not import torch, robosuite, lerobot)
    # lazy: optional X      X is an optional dependency
    # lazy: cycle with Y    importing at the top would close an import cycle with module Y

Prints the counts and every lazy import without a reason; exits 1 over ``--max-percent`` or on an unexplained one.

    .venv/bin/python scripts/check_lazy_imports.py [--max-percent 10] [--by-file] [ROOT...]
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FIRST_PARTY = ("indgen_vla", "scenes", "policy_wrappers")
REASON = re.compile(r"#\s*lazy:\s*(start-up\b|optional\s+\S|cycle with\s+\S)")
ANY_LAZY_COMMENT = re.compile(r"#\s*lazy:")
FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


@dataclass(frozen=True)
class Imp:
    """One first-party import statement: where it is, its text, whether it is lazy and whether its reason is given."""

    path: Path
    line: int
    text: str
    lazy: bool
    reason: bool
    malformed: bool  # a ``# lazy:`` comment is there but names none of the three reasons


def _first_party(node: ast.Import | ast.ImportFrom, packages: tuple[str, ...]) -> bool:
    if isinstance(node, ast.ImportFrom):
        return node.level > 0 or (node.module or "").split(".")[0] in packages
    return any(alias.name.split(".")[0] in packages for alias in node.names)


def _reason_lines(lines: list[str], node: ast.stmt) -> list[str]:
    """The import's own lines plus a comment-only line just above it."""
    own = lines[node.lineno - 1 : (node.end_lineno or node.lineno)]
    above = lines[node.lineno - 2] if node.lineno >= 2 else ""
    return own + ([above] if above.lstrip().startswith("#") else [])


def scan_file(path: Path, packages: tuple[str, ...] = FIRST_PARTY) -> list[Imp]:
    """The first-party imports of one file, lazy or not."""
    source = path.read_text(encoding="utf-8")
    lines = source.splitlines()
    found: list[Imp] = []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)) and _first_party(child, packages):
                near = _reason_lines(lines, child)
                reason = any(REASON.search(text) for text in near)
                found.append(
                    Imp(
                        path=path,
                        line=child.lineno,
                        text=lines[child.lineno - 1].strip(),
                        lazy=in_function,
                        reason=reason,
                        malformed=not reason and any(ANY_LAZY_COMMENT.search(text) for text in near),
                    )
                )
            walk(child, in_function or isinstance(child, FUNCTIONS))

    walk(ast.parse(source, filename=str(path)), False)
    return found


def scan(roots: list[Path], packages: tuple[str, ...] = FIRST_PARTY) -> list[Imp]:
    """The first-party imports of every ``*.py`` under ``roots`` (files or folders), in path order."""
    files: list[Path] = []
    for root in roots:
        files.extend([root] if root.is_file() else sorted(root.rglob("*.py")))
    return [imp for path in files for imp in scan_file(path, packages)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("roots", nargs="*", type=Path, help="files or folders (default: the three packages)")
    parser.add_argument(
        "--max-percent", type=float, default=10.0, help="the most lazy imports may be, in %% of all"
    )
    parser.add_argument("--by-file", action="store_true", help="also list the lazy count of each file")
    args = parser.parse_args(argv)
    roots = args.roots or [REPO / name for name in FIRST_PARTY]
    missing = [str(root) for root in roots if not root.exists()]
    if missing:
        print(f"error: no such file or folder: {', '.join(missing)}", file=sys.stderr)
        return 2
    imports = scan(roots)
    lazy = [imp for imp in imports if imp.lazy]
    share = 100.0 * len(lazy) / len(imports) if imports else 0.0

    def shown(path: Path) -> str:
        return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)

    if args.by_file:
        for path, n in sorted(Counter(shown(imp.path) for imp in lazy).items()):
            print(f"{n:4d}  {path}")
    unexplained = [imp for imp in lazy if not imp.reason]
    for imp in unexplained:
        what = (
            "reason not one of start-up / optional X / cycle with Y"
            if imp.malformed
            else "no '# lazy:' reason"
        )
        print(f"{shown(imp.path)}:{imp.line}: {what}: {imp.text}")
    print(
        f"first-party imports: {len(imports)}, inside functions: {len(lazy)} ({share:.1f} %, at most "
        f"{args.max_percent:g} %), without a reason: {len(unexplained)}"
    )
    return 1 if share > args.max_percent or unexplained else 0


if __name__ == "__main__":
    sys.exit(main())
