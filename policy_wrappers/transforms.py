"""Per-checkpoint-family conventions as small frozen transforms: docs/results/policy_conventions.md as code.

Each family's LIBERO evaluation prepares images and maps actions in its own way (openpi
``src/openpi/policies/libero_policy.py`` composes such steps with ``transforms.compose``). Here an image
pipeline is a ``Compose`` of frozen steps applied to one HxWx3 uint8 camera image (our raw, upside-down
render), an action pipeline a ``Compose`` applied to the (B, T, 7) chunk the model returned, and
``Conventions`` bundles them with the render size and the chunking the upstream eval uses. The adapters
take the family constant below and apply only what a spec option overrides (``Conventions.override``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from indgen_vla.core.errors import ConfigError
from policy_wrappers.image_tools import (
    GRIPPER_MODES,
    center_crop_tf,
    convert_gripper,
    flip_180,
    resize_jpeg_lanczos,
    resize_with_pad,
)

MIN_IMAGE_SIZE = 8


def _check_size(who: str, size: int) -> None:
    if int(size) < MIN_IMAGE_SIZE:
        raise ConfigError(f"{who}: image size must be >= {MIN_IMAGE_SIZE}, got {size}")


@dataclass(frozen=True)
class Flip180:
    """Rotate by 180°: LIBERO-trained checkpoints saw the simulator's render upside down."""

    def __call__(self, img: np.ndarray) -> np.ndarray:
        return flip_180(img)


@dataclass(frozen=True)
class Resize:
    """A resize to ``size`` x ``size``; the subclasses are the families' resize kernels."""

    size: int

    def __post_init__(self) -> None:
        _check_size(type(self).__name__, self.size)


@dataclass(frozen=True)
class ResizeWithPad(Resize):
    """openpi's ``image_tools.resize_with_pad`` to a square: PIL bilinear, aspect kept, zero padding."""

    def __call__(self, img: np.ndarray) -> np.ndarray:
        return resize_with_pad(img, self.size, self.size)


@dataclass(frozen=True)
class JpegLanczos(Resize):
    """OpenVLA(-OFT)'s ``resize_image``: TF's JPEG round trip (quality 95), then TF's Lanczos-3 resize."""

    def __call__(self, img: np.ndarray) -> np.ndarray:
        return resize_jpeg_lanczos(img, self.size, self.size)


@dataclass(frozen=True)
class PadResizeCv(Resize):
    """GR00T's RoboCasa sim (squarefk/robocasa ``robocasa/utils/gym_utils/gymnasium_groot.py`` ``process_img``):
    zero-pad to a square, then ``cv2.resize(img, (size, size), cv2.INTER_AREA)``, whose third positional
    argument is ``dst``, so the interpolation is cv2's default (bilinear); written here as that call does it."""

    def __call__(self, img: np.ndarray) -> np.ndarray:
        import cv2

        h, w, _ = img.shape
        if h != w:
            dim = max(h, w)
            y, x = (dim - h) // 2, (dim - w) // 2
            img = np.pad(img, ((y, y), (x, x), (0, 0)))
        if img.shape[:2] != (self.size, self.size):
            img = cv2.resize(img, (self.size, self.size), interpolation=cv2.INTER_LINEAR)
        return np.copy(img)


@dataclass(frozen=True)
class CenterCrop:
    """Base OpenVLA's LIBERO ``center_crop``: keep ``scale`` of the area, TF-bilinear back to the input size."""

    scale: float = 0.9  # run_libero_eval.py / openvla_utils.py:crop_and_resize

    def __post_init__(self) -> None:
        if not 0.0 < self.scale <= 1.0:
            raise ConfigError(f"CenterCrop: scale must be in (0, 1], got {self.scale}")

    def __call__(self, img: np.ndarray) -> np.ndarray:
        return center_crop_tf(img, self.scale)


@dataclass(frozen=True)
class GripperMap:
    """A model's gripper output -> ours (-1 open, +1 close); see ``image_tools.convert_gripper``."""

    mode: str

    def __post_init__(self) -> None:
        if self.mode not in GRIPPER_MODES:
            raise ConfigError(f"GripperMap: mode must be one of {GRIPPER_MODES}, got {self.mode!r}")

    def __call__(self, chunk: np.ndarray) -> np.ndarray:
        return convert_gripper(chunk, self.mode)


Step = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Compose:
    """Steps applied in order (openpi's ``CompositeTransform``); the empty pipeline returns its input."""

    steps: tuple[Step, ...] = ()

    def __call__(self, x: np.ndarray) -> np.ndarray:
        for step in self.steps:
            x = step(x)
        return x

    def find(self, kind: type) -> Step | None:
        """The first step of type ``kind``, or None."""
        return next((s for s in self.steps if isinstance(s, kind)), None)

    def without(self, kind: type) -> Compose:
        """This pipeline minus every step of type ``kind``."""
        return Compose(tuple(s for s in self.steps if not isinstance(s, kind)))

    def replaced(self, step: Step, *, first: bool = False) -> Compose:
        """``step`` in place of the steps of its type; added (at the front if ``first``) when there is none."""
        if self.find(type(step)) is None:
            return Compose((step, *self.steps) if first else (*self.steps, step))
        return Compose(tuple(step if isinstance(s, type(step)) else s for s in self.steps))


def compose(*steps: Step) -> Compose:
    """A pipeline of ``steps`` in order."""
    return Compose(tuple(steps))


@dataclass(frozen=True)
class Conventions:
    """One checkpoint family's LIBERO conventions (openpi's ``Group`` of input and output transforms).

    render: the square size the engine renders at (what the upstream eval rendered). images: applied to
    each camera before it is sent. actions: applied to each returned chunk. chunk: actions per query
    (None: the checkpoint decides). replan: actions executed per query, at most ``chunk`` (None: all).
    """

    render: int | None = 256  # LIBERO_ENV_RESOLUTION of every upstream LIBERO eval
    images: Compose = field(default_factory=Compose)
    actions: Compose = field(default_factory=Compose)
    chunk: int | None = None
    replan: int | None = None

    def __post_init__(self) -> None:
        if self.render is not None:
            _check_size("render", self.render)
        if self.chunk is not None and self.chunk < 1:
            raise ConfigError(f"chunk must be >= 1, got {self.chunk}")

    @property
    def flips(self) -> bool:
        """Whether the images are rotated 180° before they reach the model."""
        return self.images.find(Flip180) is not None

    def chunking(self, chunk: int | None = None, replan: int | None = None) -> tuple[int, int]:
        """(chunk size, replan steps): given values win; replan defaults to ``min(self.replan, chunk)``."""
        chunk = self.chunk if chunk is None else chunk
        if chunk is None:
            raise ConfigError("these conventions take the chunk size from the checkpoint; pass it")
        if replan is None:
            replan = chunk if self.replan is None else min(self.replan, chunk)
        return chunk, replan

    def override(
        self,
        *,
        flip: bool | None = None,
        size: int | None = None,
        crop: bool | None = None,
        gripper: str | None = None,
        render: int | None = None,
    ) -> Conventions:
        """These conventions with a spec's options applied; None keeps the family's own value.

        ``size`` replaces the resize step's size (or adds openpi's resize-with-pad when there is none).
        """
        images, actions = self.images, self.actions
        if flip is not None:
            images = images.replaced(Flip180(), first=True) if flip else images.without(Flip180)
        if size is not None:
            resize = next((s for s in images.steps if isinstance(s, Resize)), None)
            images = images.replaced(replace(resize, size=size) if resize else ResizeWithPad(size))
        if crop is not None:
            images = (
                images.replaced(images.find(CenterCrop) or CenterCrop())
                if crop
                else images.without(CenterCrop)
            )
        if gripper is not None:
            actions = actions.replaced(GripperMap(gripper))
        render = self.render if render is None else render
        return replace(self, render=render, images=images, actions=actions)


# ---- the families (docs/results/policy_conventions.md has the upstream sources of every value) ---------
# openpi pi0.5 (examples/libero/main.py): both cameras [::-1, ::-1], resize_with_pad to 224; actions are
# LIBERO's -1/+1 already (LiberoOutputs keeps actions[..., :7]); action_horizon 10, replan_steps 5.
LIBERO_OPENPI = Conventions(images=compose(Flip180(), ResizeWithPad(224)), chunk=10, replan=5)
# OpenVLA-OFT (run_libero_eval.py, openvla_utils.py): flip, JPEG + Lanczos to 224 (the server crops);
# gripper sign(2x - 1) then inverted; NUM_ACTIONS_CHUNK 8, all executed.
LIBERO_OFT = Conventions(
    images=compose(Flip180(), JpegLanczos(224)), actions=compose(GripperMap("01inv")), chunk=8
)
# Base OpenVLA (its run_libero_eval.py): agentview flipped, JPEG + Lanczos to 224, then the in-process
# center crop (0.9 of the area); gripper as OFT; one action per query.
LIBERO_OPENVLA = Conventions(
    images=compose(Flip180(), JpegLanczos(224), CenterCrop(0.9)),
    actions=compose(GripperMap("01inv")),
    chunk=1,
)
# GR00T N1.5 (examples/Libero/eval): flip, 256 sent as is (the server resizes); sign(1 - 2x); 16-step
# chunk, only action[0] executed.
LIBERO_GROOT_N15 = Conventions(
    images=compose(Flip180()), actions=compose(GripperMap("01inv")), chunk=16, replan=1
)
# GR00T N1.6+ (gr00t/eval/sim/LIBERO/libero_env.py): as N1.5, gripper -sign(2x - 1); --n_action_steps 8.
LIBERO_GROOT_N16 = replace(LIBERO_GROOT_N15, replan=8)
# lerobot (processor/env_processor.py LiberoProcessorStep): every image flipped; actions unchanged; the
# render size and the chunking come from the checkpoint.
LIBERO_LEROBOT = Conventions(render=None, images=compose(Flip180()))

# UniVLA (baaivision/UniVLA reference/RoboVLMs/eval/libero/evaluate_libero_emu.py:prepare_observation): both cameras
# flipped at 256, sent as is (the model wrapper resizes to 200 and maps actions); the 10-step FAST chunk, all executed.
LIBERO_UNIVLA = Conventions(images=compose(Flip180()), chunk=10)
# RynnVLA-002 (rynnvla-002/eval_solver_libero_continous_w_state.py:val_libero): both cameras flipped at 256, sent as
# is; the continuous head's chunk (time_horizon 5 on LIBERO-Object/Goal, 10 on Spatial/Long), all executed.
LIBERO_RYNNVLA = Conventions(images=compose(Flip180()), chunk=5)

# ---- RoboCasa365 (PandaOmron): images upright, actions in the layout's order (policy_wrappers/layouts.py) -------
# GR00T on RoboCasa365's own gym wrapper (robocasa/robocasa robocasa/wrappers/gym_wrapper.py): 256x256 upright renders
# sent as they are (the server resizes). N1.5 (RoboCasa365's fork robocasa-benchmark/Isaac-GR00T scripts/run_eval.py,
# --n_action_steps 16, PandaOmronDataConfig action_indices range(16)): the 16-step chunk, all executed. N1.6+
# (Isaac-GR00T examples/robocasa/README.md --n-action-steps 8): 16-step chunk, 8 executed. Gripper and control mode
# are thresholded at 0.5 by RoboCasa itself (no gripper map).
ROBOCASA365_GROOT_N15 = Conventions(render=256, chunk=16, replan=16)
ROBOCASA365_GROOT_N16 = Conventions(render=256, chunk=16, replan=8)
# The older set-up (groot ?keys=squarefk; Isaac-GR00T examples/robocasa/README.md, squarefk/robocasa
# gymnasium_groot.py): PandaOmronKeyConverter renders 512x512, process_img brings each camera to 256; 16-step chunk,
# 8 executed.
ROBOCASA_GROOT_N16 = Conventions(render=512, images=compose(PadResizeCv(256)), chunk=16, replan=8)
# RoboCasa365's openpi client (robocasa-benchmark/openpi examples/robocasa/main.py): RoboCasaGymEnv's 256 upright
# renders, resize_with_pad to 224; replan_steps 5 (the client asserts the server returns at least that many and
# executes only those, so the chunk we count is those 5).
ROBOCASA_OPENPI = Conventions(images=compose(ResizeWithPad(224)), chunk=5, replan=5)
