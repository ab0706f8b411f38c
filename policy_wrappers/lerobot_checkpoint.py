"""What a LeRobot checkpoint's files say before its model loads: the options a ``lerobot:`` spec takes, which of
our cameras feed its image features, and the scene it will ask for (``preview``), read without torch or lerobot.

``preview`` lets the engine build the first scenes in worker processes while the model loads (start-up, issue 28);
the loaded policy's ``PolicySpec`` is the authority, and the engine discards the early scenes when the two differ.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import PRECISIONS, TABLETOP, EnvSpec, ScenePreview
from indgen_vla.core.protocol.training_support import TrainedCell, cells_from_json
from policy_wrappers.compile import check_mode
from policy_wrappers.layouts import layout_for

IMAGE_PREFIX = "observation.images."
# Camera names seen in LeRobot checkpoints -> our cameras (LIBERO: image/image2; openpi-style; robosuite raw).
DEFAULT_CAMERA_MAP = {
    "agentview": "agentview",
    "wrist": "wrist",
    "image": "agentview",
    "image2": "wrist",
    "wrist_image": "wrist",
    "front": "agentview",
    "base_0_rgb": "agentview",
    "left_wrist_0_rgb": "wrist",
    "agentview_image": "agentview",
    "robot0_eye_in_hand_image": "wrist",
    "eye_in_hand": "wrist",
    "main": "agentview",
}
LIBERO_CAMERA_NAMES = {
    "image",
    "image2",
}  # lerobot's LIBERO env: these checkpoints were trained on flipped images
ZEROS = "zeros"  # map a feature to a black image (e.g. SmolVLA's empty_camera_i padding)
# indgen's own processor steps (policy_wrappers/lerobot_steps.py), as their class paths in policy_preprocessor.json
PROPRIO_STEP_CLASS = "policy_wrappers.lerobot_steps.ProprioAsEnvStateStep"
OBJECT_STEP_CLASS = "policy_wrappers.lerobot_steps.ObjectPosesStep"


@dataclass(frozen=True)
class LeRobotConfig:
    """Which checkpoint to load and how our Observation maps onto its input features."""

    path: str
    device: str = "cpu"
    revision: str | None = None
    camera_map: tuple[
        tuple[str, str], ...
    ] = ()  # (feature name after observation.images., our camera | zeros)
    flip_180: bool | None = None  # None: LIBERO_LEROBOT's flip iff the checkpoint uses LIBERO's camera names
    replan_steps: int | None = None  # None: the checkpoint's n_action_steps
    vlm: str | None = None  # local dir or Hub id replacing cfg.vlm_model_name (SmolVLA) and its tokenizer
    tokenizer: str | None = None  # local dir or Hub id replacing the tokenizer_processor's tokenizer_name
    precision: str = "fp32"  # "bf16": the forward runs under torch.autocast(bfloat16)
    compile: str = "off"  # torch.compile mode of the per-call forward (policy_wrappers/compile.py)
    env_spec: EnvSpec | None = None  # the scene family's contract (None: the tabletop one)

    @property
    def scene_cameras(self) -> tuple[str, ...]:
        return (self.env_spec or TABLETOP).cameras

    def __post_init__(self) -> None:
        if self.precision not in PRECISIONS:
            raise ConfigError(
                f"lerobot {self.path}: precision must be one of {list(PRECISIONS)}, got {self.precision!r}"
            )

        check_mode(self.compile, self.device, f"lerobot {self.path}")
        for feature, cam in self.camera_map:
            if cam not in (*self.scene_cameras, ZEROS):
                raise ConfigError(
                    f"lerobot {self.path}: camera {cam!r} for feature {feature!r} must be one of "
                    f"{[*self.scene_cameras, ZEROS]}"
                )
        if self.replan_steps is not None and self.replan_steps < 1:
            raise ConfigError(f"lerobot {self.path}: replan must be >= 1, got {self.replan_steps}")


OPTIONS = {  # LeRobotConfig field -> spec option
    "revision": "revision",
    "flip_180": "flip",
    "replan_steps": "replan",
    "vlm": "vlm",
    "tokenizer": "tokenizer",
    "precision": "precision",
    "compile": "compile",
}


def make_config(parsed, options, device: str, env_spec: EnvSpec | None) -> LeRobotConfig:
    """The ``LeRobotConfig`` a parsed ``lerobot:`` spec and its options name."""
    return LeRobotConfig(
        path=parsed.target,
        device=options.str("device", device),
        camera_map=parse_camera_map(options.str("cameras")),
        env_spec=env_spec,
        **options.fields(LeRobotConfig, OPTIONS),
    )


def parse_camera_map(text: str | None) -> tuple[tuple[str, str], ...]:
    """``"image:agentview,image2:wrist"`` -> pairs; features may be given with or without their prefix."""
    if not text:
        return ()
    pairs = []
    for item in text.split(","):
        feature, sep, cam = item.strip().rpartition(":")
        if not sep or not feature:
            raise ConfigError(f"bad camera mapping {item!r}; write cameras=FEATURE:agentview,FEATURE2:wrist")
        pairs.append((feature.removeprefix(IMAGE_PREFIX), cam))
    return tuple(pairs)


def resolve_cameras(
    name: str, config: LeRobotConfig, features: dict[str, tuple[int, ...]]
) -> list[tuple[str, str, tuple[int, ...]]]:
    """[(feature name, our camera or 'zeros', (C, H, W))] for every image feature (name after the prefix -> shape)."""
    explicit = dict(config.camera_map)
    unknown = sorted(set(explicit) - set(features))
    if unknown:
        raise ConfigError(
            f"policy {name}: cameras= names feature {unknown[0]!r}, which the checkpoint "
            f"lacks; its image features are {sorted(features)}"
        )
    layout = layout_for("lerobot", config.env_spec)
    defaults = dict(layout.cameras) if layout else DEFAULT_CAMERA_MAP
    out = []
    for feat, shape in features.items():
        cam = explicit.get(feat) or defaults.get(feat)
        if cam is None and feat.startswith("empty_camera_"):
            cam = ZEROS
        if cam is None:
            raise ConfigError(
                f"policy {name}: don't know which camera feeds image feature {feat!r}; "
                f"add ?cameras={feat}:{config.scene_cameras[0]} (or another of "
                f"{list(config.scene_cameras)}, or :zeros) — features: {sorted(features)}"
            )
        if len(shape) != 3 or shape[0] != 3:
            raise PolicyError(f"policy {name}: image feature {feat!r} has shape {shape}; expected (3, H, W)")
        out.append((feat, cam, shape))
    return out


def scene_view(
    config: LeRobotConfig, cams: list[tuple[str, str, tuple[int, ...]]]
) -> tuple[tuple[str, ...], tuple[int, ...] | None]:
    """The scene cameras to render (in the scene's order) and the size to render them at (the largest feature)."""
    used = {cam for _, cam, _ in cams}
    sizes = {shape[1:] for _, cam, shape in cams if cam != ZEROS}
    return tuple(c for c in config.scene_cameras if c in used), (max(sizes) if sizes else None)


def checkpoint_file(path: str, revision: str | None, filename: str, download: bool = True) -> Path | None:
    """A file of a local checkpoint dir or Hub repo (``download=False``: only from the local Hub cache)."""
    local = Path(path).expanduser()
    if local.is_dir():
        return local / filename if (local / filename).is_file() else None
    try:
        if download:
            from huggingface_hub import hf_hub_download

            return Path(hf_hub_download(path, filename, revision=revision))
        from huggingface_hub import try_to_load_from_cache

        found = try_to_load_from_cache(path, filename, revision=revision)
    except Exception:
        return None
    return Path(found) if isinstance(found, str) else None


def has_step(path: str, revision: str | None, registry_name: str, download: bool = True) -> bool:
    """Whether the saved policy_preprocessor.json has a step registered as (or with class path) ``registry_name``."""
    try:
        found = checkpoint_file(path, revision, "policy_preprocessor.json", download)
        steps = json.loads(found.read_text()).get("steps", []) if found else []
    except (OSError, ValueError, AttributeError):
        return False
    return any(registry_name in (step.get("registry_name"), step.get("class")) for step in steps)


def training_cells(path: str) -> tuple[TrainedCell, ...]:
    """The training levels ``indgen train`` wrote beside a local checkpoint (``train_info.json`` ``levels``); ()
    for any other checkpoint, or one trained on data without ``indgen demos`` sidecars."""
    info = Path(path).expanduser() / "train_info.json"
    if not info.is_file():
        return ()
    try:
        levels = json.loads(info.read_text()).get("levels")
    except (OSError, ValueError, AttributeError) as e:
        raise PolicyError(f"policy lerobot:{path}: cannot read {info}: {e}; re-run `indgen train`") from None
    return cells_from_json(levels)


def local_type(local: Path) -> str | None:
    """The policy type a local checkpoint's config.json names (None when unreadable: lerobot reports it)."""
    try:
        kind = json.loads((local / "config.json").read_text()).get("type")
    except (OSError, ValueError, AttributeError):
        return None
    return kind if isinstance(kind, str) else None


def preview(parsed, options, *, device: str = "cpu", env_spec: EnvSpec | None = None) -> ScenePreview | None:
    """The scene a local or Hub-cached checkpoint will ask for, from its config.json (None when it cannot say)."""
    try:
        config = make_config(parsed, options, device, env_spec)
        found = checkpoint_file(config.path, config.revision, "config.json", download=False)
        if found is None:  # neither a local dir nor in the Hub cache: only the load may download it
            return None
        features = json.loads(found.read_text())["input_features"]
        images = {
            k.removeprefix(IMAGE_PREFIX): tuple(f["shape"])
            for k, f in features.items()
            if f.get("type") == "VISUAL"
        }
        cams, size = scene_view(config, resolve_cameras(parsed.spec, config, images))
    except (ConfigError, PolicyError, OSError, ValueError, TypeError, KeyError, AttributeError):
        return None  # the load says what is wrong, in its own words
    env_state = any(f.get("type") == "ENV" for f in features.values())
    objects = env_state and has_step(config.path, config.revision, OBJECT_STEP_CLASS, download=False)
    return ScenePreview(cams, size, observes_objects=objects)
