"""Every Python block in docs/*.md compiles, and each call it makes to the toolkit (a name it imports from indgen_vla,
policy_wrappers or scenes, or a function another block of the page defines) binds to the real signature: a renamed
keyword or a dropped argument fails here in a second, even for blocks that need a training loop or a run to execute
(tests/indgen_vla/app/test_api.py, test_loop_docs.py and tests/docs/test_extending.py run those that can)."""

from __future__ import annotations

import ast
import builtins
import importlib
import importlib.util
import inspect
import re
from pathlib import Path

import pytest

from tests.docs.fences import code_blocks

ROOT = Path(__file__).resolve().parents[2]
OURS = ("indgen_vla", "policy_wrappers", "scenes")
PAGES = sorted(p for p in (ROOT / "docs").glob("*.md") if "```python" in p.read_text())


def blocks(text: str) -> list[str]:
    return code_blocks(text, "python")


def _defined(trees: list[ast.Module]) -> dict[str, inspect.Signature]:
    """The signatures of the functions the page's blocks define at top level (bodies dropped)."""
    out = {}
    for tree in trees:
        for node in tree.body:
            if isinstance(node, ast.FunctionDef):
                stub = ast.Module(
                    [ast.FunctionDef(node.name, node.args, [ast.Pass()], [], None, None, [])], []
                )
                ns: dict = {}
                exec(compile(ast.fix_missing_locations(stub), "<stub>", "exec"), ns)  # noqa: S102
                out[node.name] = inspect.signature(ns[node.name])
    return out


def _imported(tree: ast.Module) -> dict[str, object]:
    """The block's names bound by imports of the toolkit's modules, imported for real."""
    names: dict[str, object] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in OURS:
                    names[a.asname or a.name.split(".")[0]] = importlib.import_module(a.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in OURS:
            module = importlib.import_module(node.module)
            for a in node.names:
                names[a.asname or a.name] = getattr(module, a.name)
    return names


def _resolve(func: ast.expr, names: dict[str, object]) -> object | None:
    """``name`` or ``name.attr...`` of an imported toolkit name; None for anything else (a result's method)."""
    if isinstance(func, ast.Name):
        return names.get(func.id)
    if isinstance(func, ast.Attribute):
        base = _resolve(func.value, names)
        if base is not None and inspect.ismodule(base):
            assert hasattr(base, func.attr), f"{base.__name__} has no attribute {func.attr!r}"
            return getattr(base, func.attr)
    return None


def check_calls(code: str, defined: dict[str, inspect.Signature]) -> int:
    """Bind each toolkit call of ``code`` to its real signature (AssertionError naming the call); returns how many."""
    tree = ast.parse(code)
    names = _imported(tree)
    checked = 0
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        if isinstance(node.func, ast.Name) and node.func.id in defined:
            sig = defined[node.func.id]
        else:
            target = _resolve(node.func, names)
            if target is None or not callable(target):
                continue
            sig = inspect.signature(target)
        if any(isinstance(a, ast.Starred) for a in node.args) or any(k.arg is None for k in node.keywords):
            continue
        try:
            sig.bind(*[None] * len(node.args), **{k.arg: None for k in node.keywords})
        except TypeError as e:
            raise AssertionError(
                f"line {node.lineno}: {ast.unparse(node.func)}(...) does not fit {sig}: {e}"
            ) from None
        checked += 1
    return checked


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_python_block_compiles_and_its_calls_fit_the_api(page):
    codes = blocks(page.read_text())
    trees = [ast.parse(c, f"{page.name} block {i}") for i, c in enumerate(codes)]
    defined = _defined(trees)
    counts = [check_calls(c, defined) for c in codes]
    if any(re.search(rf"^\s*(from|import) ({'|'.join(OURS)})\b", c, re.M) for c in codes):
        assert sum(counts) > 0, f"{page.name}: no call of the toolkit found in its Python blocks"


def test_the_check_sees_a_renamed_keyword_a_missing_name_and_a_page_defined_function():
    with pytest.raises(AssertionError, match=r"evaluate\(\.\.\.\) does not fit"):
        check_calls("import indgen_vla\nindgen_vla.evaluate('standin:oracle')\n", {})
    with pytest.raises(AssertionError, match="has no attribute 'evaluat'"):
        check_calls("import indgen_vla\nindgen_vla.evaluat(policy='x')\n", {})
    with pytest.raises(AssertionError, match=r"markdown_page\(\.\.\.\) does not fit"):
        check_calls(
            "from indgen_vla.core.reporting.html_page import markdown_page\nmarkdown_page(1, 2, 3, plot=4)\n",
            {},
        )
    loop = blocks((ROOT / "docs" / "loop.md").read_text())
    defined = _defined([ast.parse(c) for c in loop])
    assert "indgen_eval" in defined and check_calls("indgen_eval(1, 2, 3, 4, 5, device='cpu')", defined) == 1
    with pytest.raises(AssertionError, match="indgen_eval"):
        check_calls("indgen_eval(1, 2, 3, 4, 5, devices='cpu')", defined)


def test_the_training_loop_fragment_uses_lerobot_trains_names():
    """loop.md's fragment for ``lerobot_train.py`` names that script's variables and goes after its ``step += 1``:
    each name it uses is bound in the function of the installed script that holds that line."""
    spec = importlib.util.find_spec("lerobot")
    if spec is None or spec.origin is None:
        pytest.skip("lerobot is not installed")
    script = Path(spec.origin).parent / "scripts" / "lerobot_train.py"
    tree = ast.parse(script.read_text())
    (fragment,) = [c for c in blocks((ROOT / "docs" / "loop.md").read_text()) if "lerobot_train.py" in c]
    holder = next(
        f
        for f in ast.walk(tree)
        if isinstance(f, ast.FunctionDef)
        and any(isinstance(n, ast.AugAssign) and ast.unparse(n) == "step += 1" for n in ast.walk(f))
    )
    bound = {a.arg for a in holder.args.args} | {
        n.id for n in ast.walk(holder) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)
    }
    used = {n.id for n in ast.walk(ast.parse(fragment)) if isinstance(n, ast.Name)} - {
        "indgen_eval",
        *dir(builtins),
    }
    assert used and used <= bound, sorted(used - bound)
