"""import-linter contract ``acyclic``: no import cycle among the modules of the root packages (dev-only; run by
``make lint`` through ``[tool.importlinter] contract_types`` in pyproject.toml, never imported by the packages).

import-linter's built-in ``acyclic_siblings`` only compares the children of a package with each other, so it
misses a module importing its own package's ``__init__`` back and cycles that leave the package. This contract
takes grimp's graph (module-level and function-level imports, ``TYPE_CHECKING`` ones too) and adds one edge
grimp folds away: ``from pkg import name`` reads the namespace of ``pkg`` (its ``__init__`` runs and binds it),
so it also counts as importing ``pkg``. A cycle is reported with the line of each import in it.
"""

from __future__ import annotations

import re
from collections import deque

import grimp
from importlinter.application import output
from importlinter.domain.contract import Contract, ContractCheck

_FROM = re.compile(r"^\s*from\s+(\.*)([\w.]*)\s+import\b")


def _is_package(graph: grimp.ImportGraph, module: str) -> bool:
    return bool(graph.find_children(module))


def _from_target(graph: grimp.ImportGraph, importer: str, line: str) -> str | None:
    """The module named by ``from X import ...`` on ``line`` (relative names resolved), else None."""
    m = _FROM.match(line)
    if not m:
        return None
    dots, name = m.groups()
    if not dots:
        return name
    anchor = importer if _is_package(graph, importer) else importer.rpartition(".")[0]
    for _ in range(len(dots) - 1):
        anchor = anchor.rpartition(".")[0]
    return f"{anchor}.{name}" if name else anchor


def import_edges(graph: grimp.ImportGraph) -> dict[str, dict[str, int]]:
    """importer -> {imported: line number} over the graph's modules, ``from pkg import submodule`` also
    importing ``pkg``."""
    modules = set(graph.modules)
    edges: dict[str, dict[str, int]] = {m: {} for m in modules}
    for importer in modules:
        for imported in graph.find_modules_directly_imported_by(importer):
            details = graph.get_import_details(importer=importer, imported=imported)
            edges[importer].setdefault(imported, min((d["line_number"] for d in details), default=0))
            parent = imported.rpartition(".")[0]
            for d in details:
                if (
                    parent in modules
                    and parent != importer
                    and _from_target(graph, importer, d["line_contents"]) == parent
                ):
                    edges[importer].setdefault(parent, d["line_number"])
    return edges


def _components(edges: dict[str, dict[str, int]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
    return sorted(found)


def _shortest_cycle(edges: dict[str, dict[str, int]], component: list[str]) -> list[str]:
    """A shortest cycle through the component's first module: [m0, m1, ..., m0]."""
    start, inside = component[0], set(component)
    came_from: dict[str, str] = {}
    queue = deque([start])
    while queue:
        v = queue.popleft()
        for w in sorted(edges[v]):
            if w == start:
                path = [v]
                while path[-1] != start:
                    path.append(came_from[path[-1]])
                return [*reversed(path), start]
            if w in inside and w not in came_from:
                came_from[w] = v
                queue.append(w)
    raise AssertionError(f"{start} is in a strongly connected component but on no cycle")


def find_cycles(graph: grimp.ImportGraph) -> list[str]:
    """One shortest cycle per group of mutually importing modules, as text with the line of each import
    (``a -> b (line 3 of a) -> a (line 7 of b)``), plus the group's other modules; [] when acyclic."""
    edges = import_edges(graph)
    found = []
    for comp in _components(edges):
        cycle = _shortest_cycle(edges, comp)
        hops = [f"{b} (line {edges[a][b]} of {a})" for a, b in zip(cycle, cycle[1:], strict=False)]
        rest = sorted(set(comp) - set(cycle))
        found.append(
            " -> ".join([cycle[0], *hops]) + (f"; also in the loop: {', '.join(rest)}" if rest else "")
        )
    return found


class AcyclicContract(Contract):
    """No module of the root packages imports itself back through other modules."""

    type_name = "acyclic"

    def check(self, graph: grimp.ImportGraph, verbose: bool) -> ContractCheck:
        cycles = find_cycles(graph)
        return ContractCheck(kept=not cycles, metadata={"cycles": cycles})

    def render_broken_contract(self, check: ContractCheck) -> None:
        cycles = check.metadata["cycles"]
        output.print_error(
            f"{len(cycles)} import cycle(s); break each by moving the shared piece into a module "
            "both import, or by importing the submodule that defines a name instead of its package:"
        )
        output.new_line()
        for text in cycles:
            output.print_error(f"- {text}", bold=False)
        output.new_line()


if __name__ == "__main__":  # python scripts/importlinter_acyclic.py: the cycles of this checkout, if any
    cycles = find_cycles(grimp.build_graph("indgen_vla", "scenes", "policy_wrappers", cache_dir=None))
    print("\n".join(cycles) or "no import cycles")
    raise SystemExit(1 if cycles else 0)
