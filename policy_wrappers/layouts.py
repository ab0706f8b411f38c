"""Each policy family's observation/action layout on a scene family whose robot is not the tabletop Panda.

A scene family's ``EnvSpec`` names its state and action segments in its own order (RoboCasa365: RoboCasa's
``convert_action`` order, arm first). A checkpoint family reads the state and writes the action in the order its own
evaluation code uses (lerobot's ``envs/robocasa.py``: base first), and calls our cameras by its own keys. A
``Layout`` holds that as frozen data; ``Reorder`` is the permutation between two orders, computed from the segment
names, so a family's convention is a table, not code. ``layout_for`` picks a family's layout by the scene's
``EnvSpec`` (None on the tabletop families, whose conventions live in ``transforms.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import EnvSpec

Parts = tuple[tuple[str, int], ...]


def spans(parts: Parts) -> dict[str, tuple[int, int]]:
    """Each named segment's [start, stop) in a vector laid out in ``parts`` order."""
    out, offset = {}, 0
    for name, size in parts:
        out[name] = (offset, offset + size)
        offset += size
    return out


def _index(src: Parts, dst: Parts, what: str) -> tuple[int, ...]:
    """Indices into a ``src``-ordered vector that give it in ``dst`` order (same names and sizes)."""
    if sorted(src) != sorted(dst):
        raise ConfigError(f"{what}: segments {[n for n, _ in dst]} do not match {[n for n, _ in src]}")
    at = spans(src)
    return tuple(i for name, _ in dst for i in range(*at[name]))


@dataclass(frozen=True)
class Reorder:
    """A vector's (..., D) named segments moved from order ``src`` to order ``dst`` (a frozen permutation)."""

    src: Parts
    dst: Parts
    what: str = "reorder"

    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", np.asarray(_index(self.src, self.dst, self.what)))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x)[..., self._index]


@dataclass(frozen=True)
class Layout:
    """One policy family's convention on one scene family (``env``: its ``EnvSpec.name``).

    cameras: (the family's key, our camera). state: the order the checkpoint reads our state in. action: the order
    it writes its action in. source: the upstream file whose formula this is (recorded in the run's manifest).
    """

    name: str
    env: str
    cameras: tuple[tuple[str, str], ...]
    state: Parts
    action: Parts
    source: str

    def state_to_policy(self, spec: EnvSpec) -> Reorder:
        """Our state (``spec.state_parts`` order) -> the order the checkpoint reads."""
        return Reorder(spec.state_parts, self.state, f"{self.name} state")

    def action_to_scene(self, spec: EnvSpec) -> Reorder:
        """The checkpoint's action -> our action (``spec.action_parts`` order)."""
        return Reorder(self.action, spec.action_parts, f"{self.name} action")

    def describe(self) -> dict:
        """What the manifest records: the convention's name and where it comes from."""
        return {"name": self.name, "source": self.source}


_RC = "robocasa_panda_omron"
# lerobot 0.6.1 src/lerobot/envs/robocasa.py: agent_pos = base_position, base_rotation,
# end_effector_position_relative, end_effector_rotation_relative, gripper_qpos (_format_raw_obs); convert_action
# splits the flat action base_motion 0:4, control_mode 4:5, end_effector_position 5:8, end_effector_rotation 8:11,
# gripper_close 11:12; envs/configs.py RoboCasaEnv names the images observation.images.<raw camera name>, rendered
# upright (RoboCasaGymEnv flips robosuite's frames) at 256x256.
LEROBOT_ROBOCASA = Layout(
    name="lerobot-robocasa (base first)",
    env=_RC,
    cameras=(("robot0_agentview_left", "robot0_agentview_left"), ("robot0_eye_in_hand", "robot0_eye_in_hand"),
             ("robot0_agentview_right", "robot0_agentview_right")),
    state=(("base_position", 3), ("base_rotation", 4), ("end_effector_position_relative", 3),
           ("end_effector_rotation_relative", 4), ("gripper_qpos", 2)),
    action=(("base_motion", 4), ("control_mode", 1), ("end_effector_position", 3), ("end_effector_rotation", 3),
            ("gripper_close", 1)),
    source="huggingface/lerobot src/lerobot/envs/robocasa.py (convert_action, _format_raw_obs)",
)  # fmt: skip
# GR00T on RoboCasa365's own gym wrapper (robocasa/robocasa robocasa/wrappers/gym_wrapper.py PandaOmronKeyConverter:
# video.robot0_agentview_left/right, video.robot0_eye_in_hand at 256x256 upright, state.<segment>, action.<segment>
# unmapped by key with gripper_close and control_mode thresholded at 0.5), as RoboCasa365's GR00T N1.5 fork trains
# and evaluates it (robocasa-benchmark/Isaac-GR00T gr00t/experiment/data_config.py PandaOmronDataConfig, read from its
# copy XingxinHE/Isaac-GR00T 9d7d7a9e): its state_keys and action_keys orders below; keys, not order, carry the
# meaning on the wire; ``action`` is the order the client concatenates the returned keys in.
GROOT_ROBOCASA365 = Layout(
    name="groot-robocasa365 (RoboCasa365 gym wrapper keys)",
    env=_RC,
    cameras=(("robot0_agentview_left", "robot0_agentview_left"), ("robot0_agentview_right", "robot0_agentview_right"),
             ("robot0_eye_in_hand", "robot0_eye_in_hand")),
    state=(("end_effector_position_relative", 3), ("end_effector_rotation_relative", 4), ("gripper_qpos", 2),
           ("base_position", 3), ("base_rotation", 4)),
    action=(("end_effector_position", 3), ("end_effector_rotation", 3), ("gripper_close", 1), ("base_motion", 4),
            ("control_mode", 1)),
    source="robocasa/robocasa robocasa/wrappers/gym_wrapper.py + robocasa-benchmark/Isaac-GR00T "
    "gr00t/experiment/data_config.py PandaOmronDataConfig (copy: XingxinHE/Isaac-GR00T)",
)  # fmt: skip
# The older set-up (``?keys=squarefk``): GR00T N1.6 (Isaac-GR00T examples/robocasa/README.md: --embodiment-tag
# ROBOCASA_PANDA_OMRON, --n-action-steps 8), its sim env squarefk/robocasa robocasa/utils/gym_utils/gymnasium_groot.py
# and robocasa/models/robots/__init__.py PandaOmronKeyConverter: video.res256_image_side_0/side_1/wrist_0 =
# agentview_left/right/eye_in_hand, rendered 512x512 upright and cv2.resize'd to 256; state.<name> per segment;
# action.<name> per segment, composed by unmap_action (gripper_close and control_mode thresholded at 0.5).
GROOT_SQUAREFK = Layout(
    name="groot-squarefk (Isaac-GR00T examples/robocasa keys)",
    env=_RC,
    cameras=(("res256_image_side_0", "robot0_agentview_left"), ("res256_image_side_1", "robot0_agentview_right"),
             ("res256_image_wrist_0", "robot0_eye_in_hand")),
    state=(("gripper_qpos", 2), ("base_position", 3), ("base_rotation", 4), ("end_effector_position_relative", 3),
           ("end_effector_rotation_relative", 4)),
    action=(("end_effector_position", 3), ("end_effector_rotation", 3), ("gripper_close", 1), ("base_motion", 4),
            ("control_mode", 1)),
    source="squarefk/robocasa robocasa/utils/gym_utils/gymnasium_groot.py + robocasa/models/robots/__init__.py",
)  # fmt: skip
GROOT_ROBOCASA_KEYS = {"robocasa365": GROOT_ROBOCASA365, "squarefk": GROOT_SQUAREFK}  # groot's ?keys=
# RoboCasa365's openpi client (robocasa-benchmark/openpi examples/robocasa/main.py, read from its copy
# J-Oyasumi/openpi_robocasa): observation/image = agentview_left, observation/wrist_image = eye_in_hand,
# observation/right_image = agentview_right (256 upright, resize_with_pad 224); observation/state =
# end_effector_position_relative, end_effector_rotation_relative, base_position, base_rotation, gripper_qpos;
# the returned actions go through RoboCasa's convert_action (arm first); replan_steps 5. A second fork,
# TRI-ML/openpi-priors (examples/robocasa/main.py, src/openpi/policies/robocasa_policy.py), sends the same state,
# resize, replan and convert_action but two images (no right_image); its RobocasaInputs builds a new dict from
# observation/image and observation/wrist_image only, so the third image is ignored there (rendered for nothing).
OPENPI_ROBOCASA = Layout(
    name="openpi-robocasa (arm first)",
    env=_RC,
    cameras=(("observation/image", "robot0_agentview_left"), ("observation/wrist_image", "robot0_eye_in_hand"),
             ("observation/right_image", "robot0_agentview_right")),
    state=(("end_effector_position_relative", 3), ("end_effector_rotation_relative", 4), ("base_position", 3),
           ("base_rotation", 4), ("gripper_qpos", 2)),
    action=(("end_effector_position", 3), ("end_effector_rotation", 3), ("gripper_close", 1), ("base_motion", 4),
            ("control_mode", 1)),
    source="robocasa-benchmark/openpi examples/robocasa/main.py (copy: J-Oyasumi/openpi_robocasa)",
)  # fmt: skip

LAYOUTS: dict[tuple[str, str], Layout] = {
    ("lerobot", _RC): LEROBOT_ROBOCASA,
    ("groot", _RC): GROOT_ROBOCASA365,
    ("openpi", _RC): OPENPI_ROBOCASA,
}
TABLETOP_NAMES = ("tabletop",)


def layout_for(family: str, spec: EnvSpec | None) -> Layout | None:
    """The family's layout on the scene family ``spec`` (None: the tabletop interface, or no scene given).

    Raises ConfigError, in one line, when the family has no convention for that scene family.
    """
    if spec is None or spec.name in TABLETOP_NAMES:
        return None
    layout = LAYOUTS.get((family, spec.name))
    if layout is None:
        known = sorted(f for f, env in LAYOUTS if env == spec.name)
        raise ConfigError(
            f"policy family {family} has no convention for scene family {spec.name} ({spec.layout}); families "
            f"with one: {', '.join(known) or 'none'}"
        )
    return checked(layout, spec)


def checked(layout: Layout, spec: EnvSpec) -> Layout:
    """``layout`` once its segments are known to be the scene family's (ConfigError, in one line, if not)."""
    for what, ours, theirs in (
        ("state", spec.state_parts, layout.state),
        ("action", spec.action_parts, layout.action),
    ):
        if not ours:
            raise ConfigError(
                f"scene family {spec.name} does not name its {what} segments (EnvSpec.{what}_parts)"
            )
        _index(ours, theirs, f"{layout.name} {what}")
    return layout
