"""The scene registry (one registered ``Scene`` subclass per family), the ``indgen scenes`` / ``indgen axes``
listings and the certify CLI's error paths."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import pickle
import subprocess
import sys

import pytest

import scenes
from indgen_vla.app.cli import main
from indgen_vla.core.errors import ConfigError, InfeasibleLevelError, SceneError, UnknownNameError
from scenes import family as registry
from scenes.family import (
    Scene,
    SceneCertificates,
    SceneEnvironment,
    get_scene,
    register_scene,
    registered_scenes,
)
from scenes.listing import builtin_scenes
from scenes.planning import resolve_scene_plan
from scenes.tabletop import PickPlace
from tests.fixtures.levels import level_env, level_param


def test_scenes_json(capsys):
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == [
        *(s.name for s in builtin_scenes()),
        "libero_object",
        "libero_spatial",
        "robocasa",
    ]
    pp = rows[0]
    assert pp["max_steps"] == 280 and "pick_y" in pp["axes"] and "milk" in pp["tasks"] and pp["needs"] is None


def _listing(tmp_path, *argv: str) -> tuple[list, list]:
    """Run the listing in a fresh interpreter without LIBERO's assets; return its rows and heavy modules loaded."""
    code = (
        "import json, sys; from indgen_vla.app.cli import main; main(sys.argv[1:]); heavy = ('torch', 'robosuite', "
        "'mujoco', 'lerobot', 'libero'); print(json.dumps(sorted(m for m in heavy if m in sys.modules)), file=sys.stderr)"
    )
    env = {**os.environ, "INDGEN_LIBERO_ASSETS": str(tmp_path), "INDGEN_CACHE": str(tmp_path / "cache")}
    r = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, env=env, timeout=120
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout), json.loads(r.stderr.strip().splitlines()[-1])


def test_libero_listed_without_assets_or_simulator(tmp_path):
    """``indgen scenes`` / ``axes`` list libero_object and its axes with no assets, importing no simulator."""
    rows, heavy = _listing(tmp_path, "scenes", "--json")
    assert heavy == [] and not (tmp_path / "cache").exists()
    lib = {r["name"]: r for r in rows}["libero_object"]
    assert lib["axes"] == ["pick_y", "goal_y", "scale", "distractor"] and lib["max_steps"] == 280
    assert "LIBERO's assets" in lib["needs"]
    if importlib.util.find_spec("libero") is not None:
        assert len(lib["tasks"]) == 10 and lib["tasks"][0] == "alphabet_soup"
        assert "missing: indgen setup libero" in lib["needs"]  # the project's own one-step fix first
    rows, heavy = _listing(tmp_path, "axes", "--json")
    assert heavy == []
    by = {r["name"]: r["scenes"] for r in rows}
    for axis in ("pick_y", "goal_y", "scale", "distractor", "pick_y+distractor"):
        assert "libero_object" in by[axis], axis
    assert "libero_object" not in by["stack"] and "libero_object" not in by["clutter"]
    assert "libero_spatial" in by["scale"] and "libero_spatial" in by["distractor"]
    assert "libero_spatial" not in by["pick_y"] and "libero_spatial" not in by["goal_y"]


def test_libero_spatial_listed_with_scale_and_distractor_only(tmp_path):
    """``indgen scenes`` lists libero_spatial with scale and distractor only; pick_y on it is a one-line error."""
    rows, _ = _listing(tmp_path, "scenes", "--json")
    spatial = {r["name"]: r for r in rows}["libero_spatial"]
    assert spatial["axes"] == ["scale", "distractor"] and spatial["max_steps"] == 280
    if importlib.util.find_spec("libero") is None:
        return
    assert len(spatial["tasks"]) == 10 and "on_the_cookie_box" in spatial["tasks"]
    env = {**os.environ, "INDGEN_LIBERO_ASSETS": str(tmp_path), "INDGEN_CACHE": str(tmp_path / "cache")}
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "indgen_vla.app.cli",
            "certify",
            "--scene",
            "libero_spatial",
            "--axis",
            "pick_y",
            "--out",
            str(tmp_path / "cert"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    err = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in err and "Traceback" not in err, err
    assert "axis of scene libero_spatial 'pick_y'" in err and "known: distractor, scale" in err


def test_axes_json_lists_every_table_row(capsys):
    assert main(["axes", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    expected = {
        "pick_y",
        "goal_y",
        "scale",
        "pick_x",
        "fixture_x",
        "horizon",
        "clutter",
        "stack",
        "distractor",
    }
    assert expected <= set(rows)
    assert rows["pick_y"]["step"] == 0.025 and rows["pick_y"]["levels"] == "-3..3"
    assert rows["goal_y"]["step"] == 0.0367 and rows["scale"]["step"] == 0.0667
    assert rows["stack"]["levels"] == "0..4" and rows["stack"]["scenes"] == ["stack"]
    assert rows["pick_y+distractor"]["scenes"] == ["pick_place", "stack", "libero_object"]


def test_tables_print(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "400")  # rich wraps cells at the terminal width
    assert main(["scenes"]) == 0
    assert main(["axes"]) == 0
    out = capsys.readouterr().out
    assert (
        "cabinet_pick" in out and "distractor" in out and "libero_object" in out and "LIBERO's assets" in out
    )


def test_piped_tables_are_not_cut_to_80_columns():
    """``indgen scenes | less`` or a log file: no ellipsised task names or readiness notes (rich's default width
    without a terminal is 80)."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    out = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", "scenes"], capture_output=True, text=True,
                         env=env, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "…" not in out.stdout and "libero_object" in out.stdout


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--scene", "stak", "--axis", "stack"], "did you mean 'stack'"),
        (["--scene", "stack", "--axis", "stak"], "did you mean 'stack'"),
        (["--scene", "stack", "--axis", "stack", "--levels", "3:9"], "outside axis stack's range"),
        (["--scene", "stack", "--axis", "stack", "--episodes", "0"], "--episodes must be >= 1"),
    ],
)
def test_certify_bad_input_is_one_line(argv, needle, tmp_path, capsys):
    assert main(["certify", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err and "Traceback" not in err


# ---- the registry ----------------------------------------------------------------------------------
@pytest.fixture
def private_registry(monkeypatch):
    """Register test scenes in a copy of the registry, dropped after the test."""
    monkeypatch.setattr(registry, "_SCENES", dict(registry._SCENES))


SLOTS = ((0.25, 0.05), (-0.18, 0.3))


def _tiny_pick():
    class TinyPick(PickPlace):
        """Pick and place with one task and its own distractor spots.

        **Task Description:** pick up the milk carton and place it in the basket.

        **Randomizations:** PickPlace's T0 jitter; the pick object's y; two distractors at ``SLOTS``.

        **Success Conditions:** PickPlace's (in the basket, released and still).
        """

        name = "tiny_pick"
        tasks = ("milk",)
        axes = ("distractor", "pick_y")
        distractor_slots = SLOTS

    return TinyPick


def test_every_family_is_registered_once_with_its_docstring_sections():
    names = [s.name for s in registered_scenes()]
    assert (
        names
        == scenes.scene_names()
        == ["pick_place", "stack", "cabinet_pick", "libero_object", "libero_spatial", "robocasa"]
    )
    for s in registered_scenes():
        assert isinstance(s, Scene) and get_scene(s.name) is s and s.default_axis == s.axes[0]
        assert all(sec in type(s).__doc__ for sec in registry.DOC_SECTIONS), s.name
    with pytest.raises(UnknownNameError, match="did you mean 'libero_spatial'"):
        get_scene("libero_spatal")
    for s in registered_scenes():  # each role its own frozen object over the family, which pickles as a value
        env, certs = s.environment, s.certificates
        assert (
            type(env) is s.Environment and type(certs) is s.Certificates and env.family is s is certs.family
        )
        assert isinstance(env, SceneEnvironment) and isinstance(certs, SceneCertificates)
        with pytest.raises(dataclasses.FrozenInstanceError):
            env.family = None
        assert pickle.loads(pickle.dumps(s)) == s and hash(pickle.loads(pickle.dumps(s))) == hash(s)
    assert get_scene("stack").environment.env_class() is get_scene("pick_place").environment.env_class()
    with pytest.raises(UnknownNameError, match="did you mean 'stack'"):
        list(scenes.get_scene("stak").tasks)


def test_a_registered_subclass_is_found_by_the_scenes_api(private_registry):
    register_scene(_tiny_pick())
    assert scenes.scene_names()[-1] == "tiny_pick"
    assert list(scenes.get_scene("tiny_pick").tasks) == ["milk"] and list(
        scenes.get_scene("tiny_pick").axes
    ) == ["distractor", "pick_y"]
    assert (
        scenes.get_scene("tiny_pick").select_tasks("all")
        == ["milk"]
        == scenes.get_scene("tiny_pick").select_tasks(None)
    )
    assert level_param("tiny_pick", None, "pick_y", 2) == level_param("pick_place", "milk", "pick_y", 2)
    resolve_scene_plan(get_scene("tiny_pick"), None, ["pick_y+distractor"])
    with pytest.raises(UnknownNameError, match="axis of scene tiny_pick 'goal_y'"):
        level_env("tiny_pick", axis="goal_y")
    # the family's own distractor slots place the distractors of its levels (make_env's default axis: distractor)
    env = level_env("tiny_pick", level=2, cameras=())
    try:
        assert env.spec.scene == "tiny_pick" and env.axis.name == "distractor" and env.spec.distractors == 2
        assert env.success_predicate is get_scene("pick_place").success_predicate
        placed = [pos[:2] for _, pos in env._rs.layout.static]
        assert placed == [pytest.approx(xy) for xy in SLOTS]
    finally:
        env.close()
    tiny = get_scene("tiny_pick")
    with pytest.raises(InfeasibleLevelError, match="tiny_pick has 2 distractor slots"):
        tiny.layout(dataclasses.replace(tiny.base("milk"), distractors=3))


def test_register_rejects_incomplete_classes(private_registry):
    class NoDoc(PickPlace):
        name = "no_doc"

    with pytest.raises(ConfigError, match="lacks the section"):
        register_scene(NoDoc)
    bad_axis = type(
        "BadAxis",
        (_tiny_pick(),),
        {"name": "bad_axis", "axes": ("pick_yy",), "__doc__": _tiny_pick().__doc__},
    )
    with pytest.raises(ConfigError, match="unknown axes"):
        register_scene(bad_axis)
    clash = type("Clash", (_tiny_pick(),), {"name": "stack", "__doc__": _tiny_pick().__doc__})
    with pytest.raises(ConfigError, match="already registered"):
        register_scene(clash)
    with pytest.raises(ConfigError, match="Scene subclasses"):
        register_scene(dict)
    no_part = type(
        "NoPart", (_tiny_pick(),), {"name": "no_part", "Environment": dict, "__doc__": _tiny_pick().__doc__}
    )
    with pytest.raises(ConfigError, match="no_part: Environment must be a SceneEnvironment subclass"):
        register_scene(no_part)
    assert "no_doc" not in scenes.scene_names() and "bad_axis" not in scenes.scene_names()


def test_select_tasks_is_the_one_task_resolution():
    assert (
        scenes.get_scene("stack").select_tasks(None)
        == ["orange_on_blue"]
        == scenes.get_scene("stack").select_tasks("")
    )
    assert scenes.get_scene("stack").select_tasks("all") == list(scenes.get_scene("stack").tasks)
    with pytest.raises(UnknownNameError, match="did you mean 'red_on_green'.*all"):
        scenes.get_scene("stack").select_tasks("red_on_gren")


@pytest.mark.skipif(importlib.util.find_spec("libero") is None, reason="needs hf-libero")
def test_libero_spatial_defaults_to_scale_and_missing_assets_are_one_line(tmp_path, monkeypatch):
    """``make_env("libero_spatial")`` once raised a bare KeyError; now its default axis is scale, and without
    LIBERO's assets it is the one-line SceneError saying how to get them."""
    assert (
        get_scene("libero_spatial").default_axis == "scale"
        and len(list(scenes.get_scene("libero_spatial").tasks)) == 10
    )
    monkeypatch.setenv("INDGEN_LIBERO_ASSETS", str(tmp_path))
    with pytest.raises(SceneError, match="not a LIBERO asset folder") as err:
        level_env("libero_spatial", cameras=())
    assert "\n" not in str(err.value)
    with pytest.raises(SceneError, match="hf download"):
        scenes.get_scene("libero_spatial").environment.check_ready()
    scenes.get_scene("stack").environment.check_ready()  # built-ins need nothing


@pytest.mark.slow
def test_libero_spatial_builds_at_its_default_axis(mini):
    env = level_env("libero_spatial", cameras=())
    try:
        assert env.axis.name == "scale" and env.level == 0 and env.max_steps == 280
        obs, info = env.reset(seed=0)
        assert obs.state.shape == (8,) and info["init_state"] == 0
    finally:
        env.close()
