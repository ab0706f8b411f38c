"""The render backend string a run's protocol fingerprint records."""

import os

from scenes.family import get_scene
from scenes.planning import scene_levels


def test_the_builder_names_the_gl_renderer_of_this_machine():
    text = scene_levels(get_scene("pick_place"), ["pick_y"]).render_backend()
    backend = os.environ.get("MUJOCO_GL", "glfw")
    assert text.endswith(f"({backend})") or text.startswith(f"unavailable ({backend})")
    if backend == "egl" and not text.startswith("unavailable"):
        assert " / " in text  # "<GL_VENDOR> / <GL_RENDERER>"
