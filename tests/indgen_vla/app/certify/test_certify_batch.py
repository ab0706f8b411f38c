"""certify_many: level jobs of several (task, axis) pairs in one pool, a deadline that ends a chunk on whole levels,
and the next chunk going on from there."""

from __future__ import annotations

import json

from indgen_vla.app.certify.batch import certify_many
from indgen_vla.app.certify.certify_config import CertifyPlan, CertifyRule
from scenes.certificates import cert_path
from scenes.family import get_scene


def test_a_chunk_cut_by_its_deadline_is_resumed_by_the_next(tmp_path):
    pairs = [("orange_on_blue", "stack")]
    lines: list[str] = []
    stack, plan, rule = get_scene("stack"), CertifyPlan(levels=[0, 1]), CertifyRule(episodes=1)
    first = certify_many(stack, pairs, plan, rule, root=tmp_path, deadline_s=0.0, log=lines.append)
    assert first[0]["levels"] == [] and any("2 level jobs not started" in x for x in lines), lines
    second = certify_many(stack, pairs, plan, rule, root=tmp_path, log=lines.append)
    assert [r["level"] for r in second[0]["levels"]] == [0, 1]
    on_disk = json.loads(cert_path(get_scene("stack"), "orange_on_blue", "stack", root=tmp_path).read_text())
    assert [(r["level"], r["n"]) for r in on_disk["levels"]] == [(0, 1), (1, 1)]
    assert (tmp_path / "SUMMARY.md").is_file()
    third = certify_many(stack, pairs, plan, rule, root=tmp_path, log=lines.append)
    assert third[0]["levels"] == second[0]["levels"]  # nothing left to run: the stored rows
