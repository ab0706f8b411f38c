"""README.md and docs/: every relative link resolves (file and heading anchor), and the README stays a front door."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
README_MAX_BYTES = 20_000  # issue 40: a front door, not a reference manual (it was 87 KB)


def prose(text: str) -> str:
    """The text outside fenced code blocks and inline code, where a link is a link."""
    text = re.sub(r"(?ms)^(```|~~~).*?^\1[ \t]*$", "", text)
    return re.sub(r"`[^`\n]*`", "", text)


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped (letters, digits, _ and - kept), spaces to -."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading anchor of a markdown page, repeated headings numbered as GitHub numbers them (-1, -2, ...)."""
    seen: dict[str, int] = {}
    out = set()
    for line in re.sub(r"(?ms)^(```|~~~).*?^\1[ \t]*$", "", page.read_text()).splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        s = slug(m.group(1))
        out.add(f"{s}-{seen[s]}" if s in seen else s)
        seen[s] = seen.get(s, 0) + 1
    return out


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """The relative links of ``page`` that point at no file or folder under ``root``, or at no heading."""
    bad = []
    for target in LINK.findall(prose(page.read_text())):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto: ...: not checked (no network)
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists() or root not in (dest, *dest.parents):
            bad.append(f"{target} (no such file in the repository)")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target} (no heading #{anchor} in {dest.relative_to(root)})")
    return bad


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_relative_link_resolves(page):
    """A moved or renamed page or heading breaks the links to it: each must name an existing file and heading."""
    assert broken_links(page) == []


def test_the_checker_sees_a_broken_link_and_a_broken_anchor(tmp_path):
    """The checker itself: a missing file, a missing heading and a link inside code (ignored)."""
    page = tmp_path / "p.md"
    links = "[x](p.md#a-b-c) [y](#top) [z](gone.md) [w](p.md#nope)\n`[q](gone2.md)`\n"
    page.write_text("# Top\n\n## A `b` (c)\n\n" + links)
    found = [b.split(" ")[0] for b in broken_links(page, tmp_path)]
    assert found == ["gone.md", "p.md#nope"]


def test_readme_is_a_front_door():
    """README.md stays short, and its two set-up commands are `make demo` and `make test`, targets the Makefile has."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.encode()) <= README_MAX_BYTES
    setup = readme.split("## Set-up", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    assert [line.split()[:2] for line in setup.strip().splitlines()] == [["make", "demo"], ["make", "test"]]
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"(?m)^demo:", makefile) and re.search(r"(?m)^test:", makefile)


def test_no_file_refers_to_a_document_outside_the_repository():
    """Docs, code and tests cite only files of the repository: no design notes kept beside it."""
    outside = re.compile(r"DESIGN\.md|\.\./shared/")
    hits = []
    tops = ("README.md", "docs", "indgen_vla", "scenes", "policy_wrappers", "scripts", "tests", "configs")
    for top in tops:
        base = ROOT / top
        for f in [base] if base.is_file() else base.rglob("*"):
            if f.suffix in (".md", ".py", ".yaml", ".sh", ".toml") and f != Path(__file__).resolve():
                hits += [f"{f.relative_to(ROOT)}:{i}" for i, line in enumerate(f.read_text().splitlines(), 1)
                         if outside.search(line)]  # fmt: skip
    assert hits == []
