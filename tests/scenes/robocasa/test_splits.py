"""RoboCasa365's split and RoboCasa's object registries, chosen once per command (``--split``, ``--obj-registries``,
else ``INDGEN_ROBOCASA_SPLIT``, ``INDGEN_ROBOCASA_OBJ_REGISTRIES``; ``scenes/robocasa/splits.py``): what RoboCasa
makes of them, where the choice goes (the worker's config, the fingerprint, the certificates' folder) and the
one-line refusals.

Upstream: robocasa/robocasa be22d659 (= the pinned rlinf-robocasa365 1.0.1, read from the installed copy):
``robocasa/utils/env_utils.py`` ``create_env`` (split -> Kitchen arguments), ``robocasa/models/scenes/
scene_registry.py`` (``LAYOUT_GROUPS_TO_IDS``, ``STYLE_GROUPS_TO_IDS``), ``robocasa/models/objects/
kitchen_object_utils.py`` (``sample_kitchen_object_helper``: a category's models split at max(n - 5, ceil(n / 2))),
``robocasa/environments/kitchen/kitchen.py`` (``Kitchen.__init__``'s ``obj_registries`` default),
``robocasa/utils/dataset_registry.py`` (``PRETRAINING_TASKS``); lerobot 0.6.1 ``lerobot/envs/robocasa.py``
(``DEFAULT_OBJ_REGISTRIES``, ``split="all"``).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
from pathlib import Path

import pytest

from indgen_vla.core.errors import ConfigError
from scenes.robocasa import splits
from tests.scenes.robocasa.test_robocasa import needs_venv

_CREATE_ENV = """
import inspect, json, sys
import robocasa.utils.env_utils as env_utils
from robocasa.environments.kitchen.kitchen import Kitchen
from robocasa.models.scenes.scene_registry import unpack_layout_ids, unpack_style_ids
from robocasa.utils.dataset_registry import PRETRAINING_TASKS, TARGET_TASKS

class Made(Exception):
    pass

def make(**kwargs):  # create_env's one robosuite.make call: its kitchen arguments, then stop before any build
    raise Made({k: kwargs.get(k) for k in ("obj_instance_split", "layout_ids", "style_ids", "layout_and_style_ids")})

env_utils.robosuite.make = make
out = {"splits": {}, "tasks": sys.argv[1:]}
for split in ("pretrain", "target", "all"):
    try:
        env_utils.create_env("PickPlaceCounterToCabinet", split=split)
    except Made as e:
        kw = e.args[0]
        pairs = kw["layout_and_style_ids"] or [(l, s) for l in unpack_layout_ids(kw["layout_ids"])
                                               for s in unpack_style_ids(kw["style_ids"])]
        out["splits"][split] = {"kwargs": kw, "pairs": [list(p) for p in pairs]}
out["registries"] = list(inspect.signature(Kitchen.__init__).parameters["obj_registries"].default)
out["none_is_all"] = unpack_layout_ids(None) == unpack_layout_ids(-3) and unpack_style_ids(None) == unpack_style_ids(-3)
out["pretrain300"] = [t for t in sys.argv[1:] if t in PRETRAINING_TASKS["pretrain300"]]
out["atomic_seen"] = [t for t in sys.argv[1:] if t in TARGET_TASKS["atomic_seen"]]
print(json.dumps(out))
"""


@needs_venv
def test_each_split_is_what_robocasas_create_env_makes_of_it():
    """The worker's kitchen arguments per split are ``create_env``'s (its one ``robosuite.make`` call, read back
    from the installed RoboCasa), ``in_split`` names exactly the split's kitchens (pretrain 2,500, target 10, all
    3,600), the default registries are ``Kitchen``'s, and every appendix-B task is a pretraining task (6 of the 17
    are also atomic_seen target tasks): the reasons the default is pretrain."""
    from scenes.family import get_scene
    from scenes.robocasa.environment import find_python

    tasks = list(get_scene("robocasa").tasks)
    out = subprocess.run(
        [str(find_python()), "-c", _CREATE_ENV, *tasks], capture_output=True, text=True, timeout=300, cwd="/"
    )
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    for split, made in got["splits"].items():
        ours = splits.kitchen_kwargs(split, splits.DEFAULT_REGISTRIES)
        pairs = {tuple(p) for p in made["pairs"]}
        assert {k: v for k, v in made["kwargs"].items() if v is not None} == {
            k: [list(p) for p in v] if k == "layout_and_style_ids" else v
            for k, v in ours.items()
            if k != "obj_registries" and v is not None
        }, split
        assert {
            (lay, sty) for lay in range(1, 61) for sty in range(1, 61) if splits.in_split(split, lay, sty)
        } == pairs
    assert [len(got["splits"][s]["pairs"]) for s in ("pretrain", "target", "all")] == [2500, 10, 3600]
    assert tuple(got["registries"]) == splits.DEFAULT_REGISTRIES and splits.DEFAULT_SPLIT == "pretrain"
    assert got["none_is_all"]  # split all draws from the list the worker's layout_ids=None drew from before
    assert got["pretrain300"] == tasks and len(got["atomic_seen"]) == 6


@needs_venv
def test_robocasa_splits_an_objects_instances_as_the_docs_say():
    """``sample_kitchen_object_helper`` keeps a category's first max(n - 5, ceil(n / 2)) models for pretrain and the
    rest for target (so a category with one model has no target instance), after drawing the category; lerobot
    evaluates split "all" with lightwheel alone."""
    from scenes.robocasa.environment import find_python

    site = next(Path(find_python()).parent.parent.glob("lib/python3*/site-packages"))
    helper = (site / "robocasa/models/objects/kitchen_object_utils.py").read_text()
    body = helper.split("def sample_kitchen_object_helper(")[1]
    assert "max(\n                    len(reg_choices) - 5, int(math.ceil(len(reg_choices) / 2))" in body
    assert "reg_choices = reg_choices[:split_th]" in body and "reg_choices = reg_choices[split_th:]" in body
    assert body.index("cat = rng.choice(valid_categories)") < body.index("split_th = max(")
    lerobot = Path(__import__("lerobot").__file__).parent / "envs/robocasa.py"
    src = lerobot.read_text()
    assert 'DEFAULT_OBJ_REGISTRIES: tuple[str, ...] = ("lightwheel",)' in src
    assert 'split=self.split if self.split is not None else "all"' in src


def test_a_bad_split_or_registry_is_one_line_listing_the_valid_ones():
    assert splits.choice({}) == ("pretrain", ("objaverse", "lightwheel"))
    assert splits.choice({splits.SPLIT_ENV: "all", splits.REGISTRIES_ENV: "lightwheel"}) == (
        "all",
        ("lightwheel",),
    )
    # the flags win, and what they set is not read from the environment (even a bad value there)
    env = {splits.SPLIT_ENV: "tset", splits.REGISTRIES_ENV: "lightwheel"}
    assert splits.choice(env, split="all") == ("all", ("lightwheel",))
    assert splits.choice({splits.SPLIT_ENV: "target"}, "all", "aigen,lightwheel") == (
        "all",
        ("aigen", "lightwheel"),
    )
    for environ, names in (
        ({splits.SPLIT_ENV: "test"}, ("pretrain (default)", "target", "all")),
        ({splits.REGISTRIES_ENV: "lightwheel,objverse"}, ("'objverse'", "objaverse, aigen, lightwheel")),
        ({splits.REGISTRIES_ENV: "lightwheel,lightwheel"}, ("repeats a registry",)),
    ):
        with pytest.raises(ConfigError) as e:
            splits.choice(environ)
        assert "\n" not in str(e.value) and all(n in str(e.value) for n in names), str(e.value)
        flags = {"split" if k == splits.SPLIT_ENV else "registries": v for k, v in environ.items()}
        with pytest.raises(ConfigError) as e:
            splits.choice({}, **flags)
        assert str(e.value).startswith("--") and all(n in str(e.value) for n in names), str(e.value)


def test_a_tree_without_a_registrys_models_is_refused_in_one_line(tmp_path):
    """A lightwheel-only download (what lerobot's docs have users fetch) cannot serve objaverse: RoboCasa would draw
    a category from it and fail on NaN probabilities; the line names the option."""
    model = tmp_path / "objects/lightwheel/apple/Apple001/model.xml"
    model.parent.mkdir(parents=True)
    model.write_text("<mujoco/>")
    line = splits.tree_problem(tmp_path, "pretrain", ("objaverse", "lightwheel"), placeholders=False)
    assert line and "'objaverse'" in line and splits.REGISTRIES_ENV in line and "\n" not in line
    assert splits.tree_problem(tmp_path, "pretrain", ("lightwheel",), placeholders=False) is None
    assert splits.tree_problem(tmp_path, "target", ("lightwheel",), placeholders=False) is None


@needs_venv
def test_the_choice_reaches_the_worker_the_fingerprint_and_the_certificates(placeholders, monkeypatch):
    """The worker builds what the user chose; runs under two splits have different ``initial_states`` (so neither
    pooled nor resumed as each other) and certificates in different folders; split all with RoboCasa's registries
    (the worker's choice before the option) keeps the fingerprint's words and the folder runs had then."""
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.certificates import certification_root
    from scenes.family import get_scene
    from scenes.robocasa.departures import PICK_T0

    sc = get_scene("robocasa")
    monkeypatch.delenv("INDGEN_CERT_DIR", raising=False)
    seen = {}
    for split, regs in (("pretrain", ""), ("target", "lightwheel"), ("all", ""), ("all", "lightwheel")):
        monkeypatch.setenv(splits.SPLIT_ENV, split)
        monkeypatch.setenv(splits.REGISTRIES_ENV, regs)
        cfg = sc.level_config(
            "PickPlaceCounterToCabinet", sc.successor(AxisRef.parse("base_y")), 1, (), (64, 64)
        )
        assert (cfg["split"], cfg["obj_registries"]) == (
            split,
            regs.split(",") if regs else ["objaverse", "lightwheel"],
        )
        facts = sc.environment.protocol_facts()
        assert facts["split"]["split"] == split
        seen[(split, regs)] = (facts["initial_states"], certification_root(get_scene("robocasa")))
    assert len({s for s, _ in seen.values()}) == len({r for _, r in seen.values()}) == 4
    legacy, root = seen[("all", "")]
    assert legacy.endswith(PICK_T0) and "split" not in legacy  # the words every run had before the option
    assert "RoboCasa365 split pretrain (layouts and styles 11..60" in seen[("pretrain", "")][0]
    assert (
        root.name == hashlib.sha1(str(placeholders.resolve()).encode()).hexdigest()[:12]
    )  # the folder before


@needs_venv
def test_a_choice_the_placeholder_tree_or_the_kitchen_cannot_serve_is_refused_in_one_line(
    placeholders, monkeypatch, tmp_path, capsys
):
    """The target split on the placeholder tree (one model per category: no target instance) exits 2 before any
    episode, and a canonical kitchen outside the split (``@11-34``: layout 11 is a pretrain layout) is refused;
    each in one line naming the fix."""
    from indgen_vla.app.cli import main
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.family import get_scene

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "standin:noop", "--scene", "robocasa", "--task", "PickPlaceCounterToCabinet",
            "--axis", "base_y", "--levels", "0:1", "--episodes", "1", "--out", str(out)]  # fmt: skip
    for environ, flag in (
        ("target", []),
        ("all", ["--split", "target"]),
    ):  # the variable, or the flag over it
        monkeypatch.setenv(splits.SPLIT_ENV, environ)
        code = main([*args, *flag])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "placeholder tree" in err, err
        assert "--split pretrain or all" in err
        assert not out.exists()
    sc, task = get_scene("robocasa"), "PickPlaceCounterToCabinet@11-34"
    base_y = sc.successor(AxisRef.parse("base_y"))
    with pytest.raises(
        ConfigError, match=r"kitchen 11-34 is not in RoboCasa365's target split .* --split pretrain or all"
    ):
        sc.configured({"split": "target"}).level_config(task, base_y, 0, (), (64, 64))
    assert sc.configured({"split": "pretrain"}).level_config(task, base_y, 0, (), (64, 64))["layout_ids"] == [
        11
    ]


@needs_venv
def test_the_flag_beats_the_variable_and_the_plans_builder_carries_it_to_the_worker(
    placeholders, monkeypatch
):
    """``--split pretrain --obj-registries lightwheel`` under ``INDGEN_ROBOCASA_SPLIT=all``: the plan resolves it
    once, and its builder (what workers and Ray actors are handed, pickled) builds each level with it, says it in
    the manifest's protocol facts and in a simulator actor's environment, after the command's scope has ended;
    the family outside the command still reads the variable."""
    import pickle

    from scenes.family import get_scene
    from scenes.planning import resolve_scene_plan

    monkeypatch.setenv(splits.SPLIT_ENV, "all")
    flags = {"split": "pretrain", "obj_registries": "lightwheel"}
    plan = resolve_scene_plan(
        get_scene("robocasa"), "PickPlaceCounterToCabinet", ["base_y"], "0:1", options=flags
    )
    builder = pickle.loads(pickle.dumps(plan.builder))  # as a worker process receives it
    successor = builder.successor("PickPlaceCounterToCabinet", "base_y")
    # what ExternalSceneEnv sends the RoboCasa worker's build (backend.py reads split and obj_registries from it)
    sent = builder.family.level_config("PickPlaceCounterToCabinet", successor, 1, (), (64, 64))
    assert (sent["split"], sent["obj_registries"]) == ("pretrain", ["lightwheel"])
    facts = (
        builder.family.environment.protocol_facts()
    )  # the manifest's protocol entry (SceneLevels.describe)
    assert facts["split"] == {"split": "pretrain", "obj_registries": ["lightwheel"],
                              "kitchens": splits.SPLIT_WORDS["pretrain"]}  # fmt: skip
    assert "split pretrain" in facts["initial_states"]
    assert builder.worker_environment() == {splits.SPLIT_ENV: "pretrain", splits.REGISTRIES_ENV: "lightwheel"}
    assert get_scene("robocasa").split_choice() == ("all", splits.DEFAULT_REGISTRIES)
    env_plan = resolve_scene_plan(get_scene("robocasa"), "PickPlaceCounterToCabinet", ["base_y"], "0:1")
    assert (
        dict(env_plan.builder.options)["split"] == "all"
    )  # no flag: the variable, resolved once all the same
    assert (
        env_plan.cell("PickPlaceCounterToCabinet", "base_y", 0).env_key
        != plan.cell("PickPlaceCounterToCabinet", "base_y", 0).env_key
    )  # the level's identity names the split: runs under the two share no T0


def test_a_scene_without_the_option_refuses_it_in_one_line(tmp_path, capsys):
    """``--split`` / ``--obj-registries`` on another family (evaluate, certify, preview): one line, exit 2."""
    from indgen_vla.app.cli import main

    for cmd in (
        ["evaluate", "--policy", "standin:noop", "--scene", "pick_place", "--axis", "pick_y", "--split", "all",
         "--out", str(tmp_path / "run")],
        ["certify", "--scene", "pick_place", "--axis", "pick_y", "--obj-registries", "lightwheel"],
        ["preview", "--scene", "pick_place", "--axis", "pick_y", "--split", "all", "--out", str(tmp_path / "p.png")],
        ["certify", "--scene", "robocasa", "--axis", "base_y", "--split", "tset"],
    ):  # fmt: skip
        assert main(cmd) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert "takes no --" in err or "pretrain (default)" in err, err
    assert not any(tmp_path.iterdir())


_T0S = """
import importlib.util, json, sys
spec = importlib.util.spec_from_file_location("backend", sys.argv[1])
backend = importlib.util.module_from_spec(spec)
spec.loader.exec_module(backend)
out = {}
for split in ("pretrain", "target"):
    cfg = {"task": "PickPlaceCounterToCabinet", "layout_ids": None, "style_ids": None, "cameras": [],
           "image_size": (64, 64), "edits": {}, "assets": sys.argv[2], "pick": None, "split": split,
           "obj_registries": ["objaverse", "lightwheel"]}
    try:
        built = backend.build(cfg)
        built.reset(0)
        meta = built.ep_meta()
        out[split] = {"kitchen": [meta["layout_id"], meta["style_id"]],
                      "splits": sorted({c["info"]["split"] for c in meta["object_cfgs"] if c.get("info")})}
        built.close()
    except Exception as e:
        out[split] = f"{type(e).__name__}: {e}"
print(json.dumps(out))
"""


@needs_venv
@pytest.mark.slow  # ~15 s CPU: two kitchens built; test_each_split_is_what_robocasas_create_env_makes_of_it keeps
# the split's arguments and test_a_choice_..._is_refused_in_one_line the refusal by default
def test_the_worker_draws_t0_from_the_split_and_says_in_one_line_when_the_tree_has_no_instance(placeholders):
    """On the placeholder tree, PickPlaceCounterToCabinet seed 0 under pretrain draws a pretrain kitchen (layout and
    style 11..60) and every object from the pretrain instances; under target (past the plan's check) RoboCasa's
    draw finds no target model and the worker says so in one line naming the two options."""
    from scenes.robocasa import backend
    from scenes.robocasa.environment import find_python

    out = subprocess.run(
        [str(find_python()), "-c", _T0S, backend.__file__, str(placeholders)],
        capture_output=True, text=True, timeout=600, cwd="/",
        env={"PATH": os.environ["PATH"], "MUJOCO_GL": "egl", "PYTHONNOUSERSITE": "1"},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert splits.in_split("pretrain", *got["pretrain"]["kitchen"]) and got["pretrain"]["splits"] == [
        "pretrain"
    ]
    line = got["target"]
    assert line.startswith("ValueError: RoboCasa drew an object category with no model under split target")
    assert "\n" not in line and splits.SPLIT_ENV in line and splits.REGISTRIES_ENV in line


@needs_venv
@pytest.mark.slow  # ~40 s CPU: a 2-episode run, its refused resume and the resume; the default test above shows the two
# splits' initial_states differ, test_fingerprint's resume tests that the engine refuses such a difference
def test_a_run_killed_under_split_all_is_not_resumed_under_pretrain(
    placeholders, tmp_path, monkeypatch, capsys
):
    """Episode 0 ran under split all; the resume under pretrain (the variable's, then the flag's over a variable
    saying all) would add an episode from other kitchens to its table: refused before any episode, in one line
    naming initial_states; under all it resumes."""
    import pandas as pd

    from indgen_vla.app.cli import main

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "standin:noop", "--scene", "robocasa", "--task", "PickPlaceCounterToCabinet",
            "--axis", "base_y", "--levels", "0", "--episodes", "2", "--max-steps", "2", "--out", str(out)]  # fmt: skip
    monkeypatch.setenv(splits.SPLIT_ENV, "all")
    assert main(args) == 0
    episodes = pd.read_parquet(out / "episodes.parquet")
    episodes[episodes.episode == 0].to_parquet(out / "episodes.parquet", index=False)  # as a kill leaves it
    for environ, flag in (("pretrain", []), ("all", ["--split", "pretrain"])):
        monkeypatch.setenv(splits.SPLIT_ENV, environ)
        capsys.readouterr()
        assert main([*args, *flag]) == 2
        err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln.startswith("error:")]
        assert len(err) == 1 and "initial_states was" in err[0] and "split pretrain" in err[0], err
        assert len(pd.read_parquet(out / "episodes.parquet")) == 1
    monkeypatch.setenv(splits.SPLIT_ENV, "all")
    assert main(args) == 0 and sorted(pd.read_parquet(out / "episodes.parquet").episode) == [0, 1]
