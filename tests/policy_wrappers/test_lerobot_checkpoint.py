"""A LeRobot checkpoint read from its files before it loads: the scene it will ask for (``preview``) must be the
one the loaded policy's spec asks for, and reading it must not import torch or lerobot (start-up, issue 28)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from indgen_vla.core.protocol.interface import ScenePreview
from policy_wrappers.specs import load_policy, preview_policy

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "checkpoints" / "act_pick_place_human"
ROBOCASA_CAMS = ("robot0_agentview_left", "robot0_agentview_right", "robot0_eye_in_hand")


def _view(spec) -> ScenePreview:
    return ScenePreview(tuple(spec.cameras), spec.image_size, spec.privileged, spec.observes_objects)


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory) -> dict[str, str]:
    """Tiny random-init ACTs with other feature names and sizes than the session's ``tiny_act``."""
    pytest.importorskip("lerobot")
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    root = tmp_path_factory.mktemp("previews")
    return {
        "front48": build_tiny_checkpoint("act", root / "front48", cameras=("front",), size=48),
        "custom": build_tiny_checkpoint("act", root / "custom", cameras=("cam_a", "cam_b"), size=24),
        "robocasa": build_tiny_checkpoint(
            "act", root / "robocasa", cameras=ROBOCASA_CAMS, size=16, state_dim=16, action_dim=12
        ),
    }


def test_the_preview_is_the_loaded_policys_scene(tiny_act, checkpoints):
    """Each case: the preview equals what the loaded policy's spec asks of the scene (cameras in the scene's
    order, the render size, object poses), so the engine keeps the scenes it built during the load."""
    from scenes.robocasa import PANDA_OMRON

    cases = [
        (f"lerobot:{tiny_act}", None),  # LIBERO's image/image2 at 32 px
        (f"lerobot:{checkpoints['front48']}", None),  # agentview only, 48 px
        (f"lerobot:{checkpoints['custom']}?cameras=cam_a:wrist,cam_b:agentview", None),
        (
            f"lerobot:{checkpoints['custom']}?cameras=cam_a:wrist,cam_b:zeros",
            None,
        ),  # a black feature: no render
        (f"lerobot:{checkpoints['robocasa']}", PANDA_OMRON),  # lerobot's RoboCasa camera names
    ]
    if SHIPPED.is_dir():
        cases.append((f"lerobot:{SHIPPED}", None))  # state-only (proprioception as environment state)
    seen = set()
    for spec, env_spec in cases:
        view = preview_policy(spec, env_spec=env_spec)
        policy = load_policy(spec, env_spec=env_spec)
        try:
            assert view == _view(policy.spec), spec
        finally:
            policy.close()
        seen.add(view)
    assert ScenePreview(("agentview", "wrist"), (32, 32)) in seen
    assert ScenePreview(("agentview",), (48, 48)) in seen and ScenePreview(("wrist",), (24, 24)) in seen
    assert ScenePreview(ROBOCASA_CAMS, (16, 16)) in seen


def test_a_previewed_object_policy_asks_for_object_poses(tmp_path, tiny_act):
    """``observes_objects`` comes from the saved steps: an ENV feature with indgen's object step, not without."""
    import shutil

    from policy_wrappers.lerobot_checkpoint import OBJECT_STEP_CLASS, PROPRIO_STEP_CLASS

    ckpt = tmp_path / "objects"
    shutil.copytree(tiny_act, ckpt)
    config = json.loads((ckpt / "config.json").read_text())
    config["input_features"] = {
        "observation.state": {"type": "STATE", "shape": [8]},
        "observation.environment_state": {"type": "ENV", "shape": [21]},
    }
    (ckpt / "config.json").write_text(json.dumps(config))
    pre = json.loads((ckpt / "policy_preprocessor.json").read_text())
    pre["steps"].insert(0, {"class": OBJECT_STEP_CLASS, "config": {}})
    (ckpt / "policy_preprocessor.json").write_text(json.dumps(pre))
    assert preview_policy(f"lerobot:{ckpt}") == ScenePreview((), None, observes_objects=True)
    pre["steps"][0]["class"] = PROPRIO_STEP_CLASS
    (ckpt / "policy_preprocessor.json").write_text(json.dumps(pre))
    assert preview_policy(f"lerobot:{ckpt}") == ScenePreview((), None, observes_objects=False)


def test_no_preview_where_the_files_cannot_say(tmp_path, tiny_act):
    """None (the engine then builds scenes after the load, which reports what is wrong): other families, a
    missing directory, a Hub id not in the local cache, an option the load refuses, an unmapped feature."""
    assert preview_policy("standin:random") is None
    assert preview_policy(f"lerobot:{tmp_path / 'missing'}") is None
    assert preview_policy("lerobot:nobody/not-cached") is None
    assert preview_policy(f"lerobot:{tiny_act}?precision=fp8") is None
    assert preview_policy("openpi:ws://127.0.0.1:9") is None  # never connects
    (tmp_path / "odd").mkdir()
    (tmp_path / "odd" / "config.json").write_text(
        json.dumps(
            {
                "type": "act",
                "input_features": {"observation.images.top": {"type": "VISUAL", "shape": [3, 8, 8]}},
            }
        )
    )
    assert preview_policy(f"lerobot:{tmp_path / 'odd'}") is None  # which camera feeds "top": the load asks


def test_a_hub_cached_checkpoint_is_previewed_offline(tiny_act, hub_cache):
    """A Hub id already in the local cache is read from there (no download: HF_HUB_OFFLINE is set)."""
    hub_cache(tiny_act, "indgen-test/tiny-act")
    assert preview_policy("lerobot:indgen-test/tiny-act") == ScenePreview(("agentview", "wrist"), (32, 32))


def test_previewing_imports_neither_torch_nor_lerobot(tiny_act):
    code = (
        "import sys; from policy_wrappers.specs import preview_policy; "
        f"v = preview_policy('lerobot:{tiny_act}'); "
        "print(v.cameras, 'torch' in sys.modules, 'lerobot' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.stdout.split() == ["('agentview',", "'wrist')", "False", "False"], out.stderr


def test_indgens_step_class_paths_are_the_classes():
    """The class paths the preview looks for in policy_preprocessor.json are where lerobot imports the steps."""
    pytest.importorskip("lerobot")
    from policy_wrappers.lerobot_checkpoint import OBJECT_STEP_CLASS, PROPRIO_STEP_CLASS
    from policy_wrappers.lerobot_steps import ObjectPosesStep, ProprioAsEnvStateStep

    assert PROPRIO_STEP_CLASS == f"{ProprioAsEnvStateStep.__module__}.{ProprioAsEnvStateStep.__qualname__}"
    assert OBJECT_STEP_CLASS == f"{ObjectPosesStep.__module__}.{ObjectPosesStep.__qualname__}"
