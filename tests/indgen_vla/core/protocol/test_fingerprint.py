"""Protocol fingerprints: one field differing at a time refuses pairing when it changes outcomes, never otherwise."""

import copy
import json
from pathlib import Path

import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.protocol.fingerprint import (
    OUTCOME_FIELDS,
    ProtocolMismatchError,
    check_comparable,
    differences,
    digest,
)


def base() -> dict:
    return {
        "scene": "pick_place", "family": "scenes.tabletop.PickPlace",
        "simulator": {"robosuite": "1.4.0", "mujoco": "3.8.1"}, "assets": "shipped", "horizon": 280,
        "settle_steps": 0, "initial_states": "seeded", "cameras": ["agentview"], "image_size": [128, 128],
        "render_backend": "Mesa / llvmpipe (egl)",
        "policy": {"family": "lerobot", "chunk_size": 10, "replan_steps": 5, "flip_180": True, "conventions": "C()"},
        "certificates": {"milk/pick_y/0": "certified"}, "plan_sha256": "ab",
    }  # fmt: skip


EDITS = {
    "scene": "stack", "family": "x.Other", "simulator": {"robosuite": "1.5.2", "mujoco": "3.8.1"},
    "assets": {"root": "/mini", "listing_sha256": "cd"}, "horizon": 300, "settle_steps": 10,
    "initial_states": "LIBERO init files", "cameras": ["agentview", "wrist"], "image_size": [256, 256],
    "render_backend": "NVIDIA Corporation / NVIDIA H100 (egl)",
}  # fmt: skip


@pytest.mark.parametrize("field", OUTCOME_FIELDS)
def test_each_outcome_field_alone_refuses_pairing_in_one_line_naming_it(field):
    other = {**base(), field: EDITS[field]}
    assert [(f, changes) for f, _, _, changes in differences(base(), other)] == [(field, True)]
    with pytest.raises(
        ProtocolMismatchError, match=rf"^A and B were made under different protocols.*: {field} is "
    ) as e:
        check_comparable([("A", base()), ("B", other)])
    assert "\n" not in str(e.value) and "--allow-protocol-mismatch" in str(e.value)
    lines = check_comparable([("A", base()), ("B", other)], allow=True)
    assert len(lines) == 1 and f"{field} differs (changes outcomes)" in lines[0]


def test_conventions_refuse_within_one_policy_family_only():
    flipped = copy.deepcopy(base())
    flipped["policy"]["flip_180"] = False
    with pytest.raises(ProtocolMismatchError, match="policy.flip_180 is true vs false"):
        check_comparable([("A", base()), ("B", flipped)])
    other_family = copy.deepcopy(flipped)
    other_family["policy"]["family"] = "openpi"
    lines = check_comparable([("A", base()), ("B", other_family)])  # comparing two families is the point
    assert any("policy.flip_180 differs (informational)" in x for x in lines)


def test_history_steps_are_in_the_policys_conventions_only_when_it_sees_history():
    """A policy seeing the step before each query (RynnVLA-002) is another protocol than one seeing the query's
    frames only; policies without history keep the fingerprints they had."""
    from indgen_vla.core.protocol.fingerprint import policy_conventions
    from indgen_vla.core.protocol.interface import PolicySpec

    plain = policy_conventions(PolicySpec("rynnvla", "x"), None)
    seeing = policy_conventions(PolicySpec("rynnvla", "x", history_steps=1), None)
    assert "history_steps" not in plain and seeing == {**plain, "history_steps": 1}
    a, b = copy.deepcopy(base()), copy.deepcopy(base())
    b["policy"]["history_steps"] = 1
    with pytest.raises(ProtocolMismatchError, match="policy.history_steps"):
        check_comparable([("A", a), ("B", b)])


def test_certificates_and_plan_are_shown_but_never_refuse():
    other = {**base(), "certificates": {}, "plan_sha256": "ef"}
    lines = check_comparable([("A", base()), ("B", other)])
    assert [x.split(":")[1].strip() for x in lines] == [
        "certificates differs (informational)",
        "plan_sha256 differs (informational)",
    ]
    assert check_comparable([("A", base()), ("B", None)]) == [
        "B: no protocol fingerprint (a real-robot run, an imported one, or one made before fingerprints were recorded); "
        "comparability not checked"
    ]


@pytest.mark.slow  # ~14 s: two runs at two horizons
def test_compare_refuses_runs_with_different_horizons_and_the_flag_lets_it_through(tmp_path, capsys):
    common = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0",
              "--episodes", "2", "--workers", "1"]  # fmt: skip
    assert main([*common, "--max-steps", "2", "--out", str(tmp_path / "a")]) == 0
    assert main([*common, "--max-steps", "3", "--out", str(tmp_path / "b")]) == 0
    fp = json.loads((tmp_path / "a" / "manifest.json").read_text())["fingerprint"]
    assert (
        fp["horizon"] == 2
        and fp["render_backend"].startswith("none")
        and fp["certificates"] == {"milk/pick_y/0": "certified"}
    )
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(tmp_path / "c")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "horizon is 2 vs 3" in err[0]
    args = [
        "compare",
        str(tmp_path / "a"),
        str(tmp_path / "b"),
        "--out",
        str(tmp_path / "c"),
        "--allow-protocol-mismatch",
    ]
    assert main(args) == 0
    assert "horizon differs (changes outcomes): 2 vs 3" in (tmp_path / "c" / "compare.md").read_text()


def _killed_after_one_episode(tmp_path, edit) -> tuple[list[str], Path, dict]:
    """A 2-episode run whose manifest ``edit`` rewrites (another protocol), cut back to its first episode as a kill
    leaves it: the evaluate argv that resumes it, its directory, and the manifest as the run first wrote it."""
    import pandas as pd

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0",
            "--episodes", "2", "--workers", "1", "--max-steps", "2", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    first = json.loads((out / "manifest.json").read_text())
    manifest = copy.deepcopy(first)
    edit(manifest)
    (out / "manifest.json").write_text(json.dumps(manifest))
    episodes = pd.read_parquet(out / "episodes.parquet")
    episodes[episodes.episode == 0].to_parquet(out / "episodes.parquet", index=False)
    return args, out, first


def test_a_resume_under_another_protocol_is_refused_in_one_line_and_the_flag_records_it(tmp_path, capsys):
    """A killed run resumed where the simulator differs (here the stored fingerprint names another MuJoCo) would mix
    two protocols' episodes in one table: refused before any episode runs, nothing on disk lost; with
    --allow-protocol-mismatch it goes on and the manifest records the change."""
    import pandas as pd

    def elsewhere(manifest: dict) -> None:  # as if started on another machine, then killed
        manifest["fingerprint"]["simulator"]["mujoco"] = "0.0.1"

    args, out, manifest = _killed_after_one_episode(tmp_path, elsewhere)
    mujoco = manifest["fingerprint"]["simulator"]["mujoco"]
    capsys.readouterr()
    assert main(args) != 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]  # notes aside
    assert len(err) == 1 and "simulator was" in err[0] and '"mujoco": "0.0.1"' in err[0], err
    assert "--allow-protocol-mismatch" in err[0]
    assert len(pd.read_parquet(out / "episodes.parquet")) == 1  # refused before any episode
    assert main([*args, "--allow-protocol-mismatch"]) == 0
    assert "resumed under another protocol: simulator" in capsys.readouterr().err
    manifest = json.loads((out / "manifest.json").read_text())
    (change,) = manifest["protocol_changes"]
    assert change["field"] == "simulator" and change["now"]["mujoco"] == mujoco
    assert sorted(pd.read_parquet(out / "episodes.parquet").episode) == [0, 1]


def test_a_resume_under_other_scene_facts_is_refused(tmp_path, capsys):
    """A run started when the scene drew its initial states otherwise (RoboCasa's pick_x window rule 1, say) holds
    the old facts in its resolved plan and its fingerprint alike: the resume weighs today's scene facts, not the
    manifest's copy, and refuses in the one protocol-mismatch line."""
    import pandas as pd

    def older_rule(manifest: dict) -> None:
        manifest["resolved"]["environment"]["protocol"]["initial_states"] = "an older rule"
        manifest["fingerprint"]["initial_states"] = "an older rule"

    args, out, _ = _killed_after_one_episode(tmp_path, older_rule)
    capsys.readouterr()
    assert main(args) != 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]  # notes aside
    assert (
        len(err) == 1
        and "initial_states was an older rule" in err[0]
        and "--allow-protocol-mismatch" in err[0]
    )
    assert len(pd.read_parquet(out / "episodes.parquet")) == 1  # refused before any episode


def test_compare_shows_the_policys_conventions_as_the_key_value_pairs_that_differ(tmp_path, capsys):
    """The fingerprint stores a policy's conventions as their repr (kept as is: changing it would change every run's
    fingerprint); compare.md and the terminal show the differing keys instead of a cut-off repr."""
    from policy_wrappers.transforms import LIBERO_LEROBOT, LIBERO_OPENPI
    from tests.indgen_vla.core.reporting.test_report import make_run

    fa, fb = base(), base()
    fa["policy"].update(family="openpi", conventions=repr(LIBERO_OPENPI))
    fb["policy"].update(family="lerobot", conventions=repr(LIBERO_LEROBOT))
    a = make_run(tmp_path / "a", {0: (9, 10), 1: (5, 10)})
    b = make_run(tmp_path / "b", {0: (8, 10), 1: (4, 10)}, regime="h+mg")
    a.update_manifest(fingerprint=fa)
    b.update_manifest(fingerprint=fb)
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    want = ("policy.conventions differs (informational): render=256, images=Flip180 + ResizeWithPad(size=224), "
            "chunk=10, replan=5 vs render=None, images=Flip180, chunk=None, replan=None")  # fmt: skip
    assert want in (tmp_path / "c" / "compare.md").read_text() and want in capsys.readouterr().out
    assert json.loads((a.path / "manifest.json").read_text())["fingerprint"] == fa  # the data is untouched
    # one family, other conventions: the refusal names the differing keys; no conventions at all reads "none"
    fb["policy"]["family"] = "openpi"
    with pytest.raises(
        ProtocolMismatchError, match=r"policy.conventions is render=256, images=Flip180 \+ Resize"
    ):
        check_comparable([("A", fa), ("B", fb)])
    fb["policy"]["conventions"] = None
    line = check_comparable([("A", fa), ("B", fb)], allow=True)[0]
    assert line.endswith("render=256, images=Flip180 + ResizeWithPad(size=224), actions=none, chunk=10, replan=5 "
                         "vs none")  # fmt: skip


def test_two_long_texts_are_shown_from_just_before_they_part():
    """RoboCasa's initial_states under two splits share some 400 characters: cut at 60, both would read the same;
    shown from 12 characters before they part, the refusal names what changed. Short or unalike texts: as they are."""
    from indgen_vla.core.protocol.fingerprint import show_difference

    a = "RoboCasa's own reset from each episode's seed " * 8 + "of that range"
    b = a + "; RoboCasa365 split pretrain (layouts and styles 11..60)"
    was, now = show_difference("initial_states", a, b, width=60)
    assert was == "…" + a[-12:] and now.startswith("…" + a[-12:] + "; RoboCasa365 split pretrain")
    assert show_difference("initial_states", "an older rule", a, width=60)[0] == "an older rule"


def test_numerics_warn_where_a_neural_policys_bits_can_differ():
    """Another instruction set or torch build is a warning; another CPU model alone is none (equal kernels); equal
    numerics, or a run made before they were recorded, none."""
    from indgen_vla.core.protocol.fingerprint import numerics_warning

    avx512 = {"machine": "x86_64", "cpu": "AMD EPYC", "cpu_isa": "avx512", "torch": "2.11.0"}
    avx2 = {**avx512, "cpu": "Intel Xeon", "cpu_isa": "avx2"}
    line = numerics_warning(avx512, avx2, "resumed")
    assert line.startswith("resumed on other numerics (cpu_isa avx512 vs avx2; cpu AMD EPYC vs Intel Xeon)")
    assert "\n" not in line and "What is bit-equal across machines" in line
    assert numerics_warning(avx512, dict(avx512), "resumed") is None
    assert numerics_warning(avx512, {**avx512, "cpu": "AMD EPYC 9654"}, "resumed") is None
    assert numerics_warning(None, avx2, "resumed") is None


def test_a_resume_under_another_worker_count_warns_for_a_batched_policy_only():
    """A batched policy's forward is padded to the worker count; per-episode (unbatched) policies, equal counts and
    ``auto`` give no line."""
    from indgen_vla.core.protocol.fingerprint import workers_warning

    line = workers_warning(1, 2, batched=True)
    assert line.startswith("resumed with --workers 2, the run began with --workers 1: ") and "\n" not in line
    assert line.endswith("resume with --workers 1 for bit-equal outcomes")
    assert workers_warning(1, 2, batched=False) is None and workers_warning(2, 2, batched=True) is None
    assert workers_warning("auto", 2, batched=True) is None and workers_warning(None, 2, batched=True) is None


def test_cpu_isa_is_the_capability_torch_dispatches_to(monkeypatch):
    """Read from the CPU's flags without importing torch, it names what torch itself reports on this machine, and
    follows ATen's rule on other flag sets and its override variable."""
    import torch

    from indgen_vla.core.protocol.fingerprint import cpu_isa

    assert cpu_isa() == torch.backends.cpu.get_cpu_capability().lower()
    assert cpu_isa({"avx2", "fma", "avx512f"}) == "avx2"  # AVX512 needs vl, bw and dq too
    assert cpu_isa({"avx2", "fma", "avx512f", "avx512vl", "avx512bw", "avx512dq"}) == "avx512"
    assert cpu_isa({"sse4_2"}) == "default"
    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "AVX2")
    assert cpu_isa() == "avx2"


def test_a_resume_on_other_numerics_warns_and_records_it(tmp_path, capsys):
    """A killed run resumed where torch dispatches to another instruction set goes on (the simulator's protocol is
    the same) but says so in one line and records the change in the manifest."""

    def elsewhere(manifest: dict) -> None:  # as if started on an AVX2 machine, then killed
        manifest["fingerprint"]["numerics"] = {**manifest["fingerprint"]["numerics"], "cpu_isa": "avx2"}

    args, out, first = _killed_after_one_episode(tmp_path, elsewhere)
    numerics = first["fingerprint"]["numerics"]
    assert {"machine", "cpu", "cpu_isa", "torch"} <= set(numerics)
    capsys.readouterr()
    assert main(args) == 0
    assert f"resumed on other numerics (cpu_isa avx2 vs {numerics['cpu_isa']}" in capsys.readouterr().err
    manifest = json.loads((out / "manifest.json").read_text())
    (change,) = manifest["numerics_changes"]
    assert change["was"]["cpu_isa"] == "avx2" and change["now"] == numerics


def test_a_family_recorded_under_its_old_module_is_the_same_family():
    """scenes/catalog.py's families moved to scenes/tabletop/ unchanged: a run started before resumes and compares."""
    old = base()
    old["family"] = "scenes.catalog.PickPlace"
    assert differences(old, base()) == [] and digest(old) == digest(base())
    other = base()
    other["family"] = "scenes.catalog.Stack"
    assert [d[0] for d in differences(other, base())] == ["family"]
