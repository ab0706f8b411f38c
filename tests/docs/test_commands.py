"""Every ``indgen`` command the docs show in a code block parses with today's CLI (the passthrough commands with their
own parsers), so a reader who copies one gets a run, not a usage error. Blocks labelled ``text`` hold synopses
(``[--flag]``, ``a | b``) and are skipped; ``...`` stands for flags left out. Every ``scripts/`` command they quote
(benchmarks, studies) names a script and flags that exist."""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import shlex
from pathlib import Path

import pytest

from indgen_vla.app import cli

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def commands(markdown: str) -> list[list[str]]:
    """The argument lists after ``indgen`` in the page's code blocks (not ``text``), one per shell command."""
    found = []
    for lang, block in re.findall(r"^ *```(\w*)\n(.*?)^ *```", markdown, flags=re.S | re.M):
        if lang == "text":
            continue
        for line in block.replace("\\\n", " ").splitlines():
            for part in re.split(r"&&|;|\|", line.strip().removeprefix("$ ")):
                try:
                    words = shlex.split(part, comments=True)
                except ValueError:  # not shell (a quote in prose)
                    continue
                while words and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=\S*", words[0]):
                    words.pop(0)  # VAR=value before the command
                if words and Path(words[0]).name == "indgen":
                    args = [w for w in words[1:] if w != "..."]
                    cut = next((i for i, w in enumerate(args) if re.fullmatch(r"\d?>>?", w)), len(args))
                    found.append(args[:cut])  # without a redirection of the output
    return found


def parse_error(argv: list[str]) -> str | None:
    """The usage error ``indgen ARGV`` gives before running anything, or None when it parses."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            args, rest = cli.build_parser().parse_known_args(argv)
            if args.command in cli.PASSTHROUGH:
                module = cli.HANDLERS[args.command].partition(":")[0]
                importlib.import_module(module).build_parser().parse_args(rest)
            elif rest:
                return f"unrecognized arguments: {' '.join(rest)}"
    except SystemExit as e:
        return None if e.code == 0 else (err.getvalue().strip().splitlines() or [f"exit {e.code}"])[-1]
    return None


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_command_in_the_docs_parses(page):
    bad = [f"indgen {shlex.join(a)}: {e}" for a in commands(page.read_text()) if (e := parse_error(a))]
    assert not bad, "\n".join(bad)


def test_the_docs_show_commands_of_every_kind():
    shown = [a for p in PAGES for a in commands(p.read_text())]
    assert len(shown) >= 80
    assert {a[0] for a in shown if a} >= {
        "evaluate",
        "report",
        "compare",
        "demos",
        "train",
        "real",
        "blockenv",
    }


def test_the_check_sees_a_renamed_flag_a_missing_argument_and_skips_synopses():
    page = """
```bash
MUJOCO_GL=egl .venv/bin/indgen evaluate --policy standin:oracle --scene pick_place --axis pick_y --episdoes 5 \\
    --out runs/x > log.txt
cd runs && indgen demos --scene pick_place --out data/human   # --n left out
indgen train data/human --out ckpt ... --steps 10
```
```text
indgen evaluate --policy SPEC [--episodes 50]
```
"""
    found = commands(page)
    assert [a[0] for a in found] == ["evaluate", "demos", "train"] and found[0][-1] == "runs/x"
    errors = [parse_error(a) for a in found]
    assert "unrecognized arguments: --episdoes 5" in errors[0]
    assert "required: --n" in errors[1] and errors[2] is None


UPSTREAM_SCRIPTS = {
    "serve_policy.py",
    "deploy.py",
    "run_eval.py",
    "lerobot_train.py",
}  # openpi's, GR00T's, lerobot's


def script_problems(markdown: str) -> list[str]:
    """Each of our ``scripts/NAME.py`` the page quotes that does not exist, and each ``--flag`` quoted after one that
    is not a literal in the script or its ``scripts/_*.py`` helpers (upstream scripts of those names and
    ``tests/scripts/`` paths left out)."""
    helpers = "".join(h.read_text() for h in (ROOT / "scripts").glob("_*.py"))
    pat = r"(?<![\w/])(?<!tests/)scripts/([\w/]+\.py)((?:[ \t]+(?:\\\n\s*)?(?!scripts/)[^\s`|;]+)*)"
    bad = []
    for name, tail in re.findall(pat, markdown):
        script = ROOT / "scripts" / name
        if Path(name).name in UPSTREAM_SCRIPTS:
            continue
        if not script.is_file():
            bad.append(f"scripts/{name}: no such script")
            continue
        source = script.read_text() + helpers
        for flag in re.findall(r"(?<![\w-])(--[a-z][\w-]*)", tail):
            if not any(f"{q}{flag}{q}" in source for q in "\"'"):
                bad.append(f"scripts/{name} {flag}: no such flag")
    return list(dict.fromkeys(bad))


@pytest.mark.parametrize(
    "page", [*PAGES, *sorted((ROOT / "docs" / "results").rglob("*.md"))], ids=lambda p: p.name
)
def test_every_script_and_flag_the_docs_quote_exists(page):
    """A benchmark re-run as written finds its script and its flags."""
    bad = script_problems(page.read_text())
    assert not bad, "\n".join(bad)


def test_the_script_check_sees_a_renamed_script_and_flag():
    page = ("re-run `scripts/bench_ray.py --sims 2 --simz 3`, `scripts/bench_rey.py`; `tests/scripts/test_gpu_kit.py`, "
            "openpi's `scripts/serve_policy.py --env LIBERO`")  # fmt: skip
    assert script_problems(page) == [
        "scripts/bench_ray.py --simz: no such flag",
        "scripts/bench_rey.py: no such script",
    ]
