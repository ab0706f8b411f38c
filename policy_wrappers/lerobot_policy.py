"""``lerobot:<hub id or local dir>`` — any LeRobot ``PreTrainedPolicy`` with its saved pre/post processors.

Loading follows lerobot's own eval path (``scripts/lerobot_eval.py``, ``rollout/context.py``):
``PreTrainedConfig.from_pretrained`` -> ``get_policy_class(type).from_pretrained(path, config=cfg)`` ->
``make_pre_post_processors(cfg, pretrained_path=path, preprocessor_overrides={"device_processor": ...})``.
Acting mirrors ``envs/utils.py:preprocess_observation`` (uint8 HWC -> float CHW in [0, 1]) plus LIBERO's
env processor (180° flip), then ``predict_action_chunk`` and the postprocessor (unnormalise) on the chunk.
On a scene family with its own robot (RoboCasa365) the scene's ``EnvSpec`` picks lerobot's layout there
(``policy_wrappers/layouts.py``: feature names, the state order the checkpoint reads, its action order).
ACT with ``temporal_ensemble_coeff`` acts through its own ``select_action`` (one ensembled action per step),
as lerobot's eval does.
"""

from __future__ import annotations

import contextlib
import threading
from collections import deque
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import (
    ACTION_DIM,
    OBJECT_DIM,
    QUERY_KEY,
    TABLETOP,
    EnvSpec,
    Observation,
    PolicySpec,
    ScenePreview,
    validate_chunk,
)
from indgen_vla.core.protocol.seeding import episode_seed
from policy_wrappers import lerobot_checkpoint, lerobot_variants
from policy_wrappers.compile import compile_forward
from policy_wrappers.layouts import layout_for
from policy_wrappers.lerobot_checkpoint import (
    IMAGE_PREFIX,
    LIBERO_CAMERA_NAMES,
    OBJECT_STEP_CLASS,
    PROPRIO_STEP_CLASS,
    ZEROS,
    LeRobotConfig,
    has_step,
    local_type,
    make_config,
    resolve_cameras,
    scene_view,
)
from policy_wrappers.lerobot_import import one_package_scan, policy_package
from policy_wrappers.transforms import LIBERO_LEROBOT, Conventions, Flip180

# torch's default generators are per process: instances take turns, each with its own generator states (_own_rng)
_RNG_LOCK = threading.Lock()
NO_CONVENTIONS = Conventions(render=None)  # other checkpoints: images as rendered (unless ?flip=1)


def _near_local_dir(local: Path) -> Path | None:
    """For a spec ``DIR/NAME`` that loaded neither as a directory nor as a Hub id: the closest directory name
    beside it when ``DIR`` exists here (a typo of a local checkpoint path), else None."""
    import difflib

    parent = local.parent
    if str(parent) in ("", ".") or not parent.is_dir():
        return None
    names = sorted(p.name for p in parent.iterdir() if p.is_dir())
    match = difflib.get_close_matches(local.name, names, n=1, cutoff=0.6)
    return parent / match[0] if match else None


class LeRobotPolicy:
    """A LeRobot policy in-process; batched when it needs no observation history (n_obs_steps == 1)."""

    def __init__(self, name: str, config: LeRobotConfig, family: str = "lerobot"):
        self.config = config
        self._name = name
        spec_env = config.env_spec
        self.layout = layout_for("lerobot", spec_env)  # None on the tabletop families
        self._state_in = self.layout.state_to_policy(spec_env) if self.layout else None
        self._action_out = self.layout.action_to_scene(spec_env) if self.layout else None
        self._action_dim = (spec_env or TABLETOP).action_dim
        self._state_dim = (spec_env or TABLETOP).state_dim
        self._load()
        if config.compile != "off":
            compile_forward(self.policy, config.compile, config.device, f"policy {name}")
        features = {k.removeprefix(IMAGE_PREFIX): tuple(f.shape) for k, f in self.cfg.image_features.items()}
        self._cams = resolve_cameras(name, config, features)
        cams, image_size = scene_view(config, self._cams)
        libero = any(feat in LIBERO_CAMERA_NAMES for feat, _, _ in self._cams)
        self.conventions = (LIBERO_LEROBOT if libero else NO_CONVENTIONS).override(flip=config.flip_180)
        chunk, replan = self._chunking()
        # ACT's temporal ensembling averages every step's new chunk with the earlier ones (per episode)
        self._ensemble = getattr(self.cfg, "temporal_ensemble_coeff", None) is not None
        if self._ensemble:
            chunk, replan = 1, 1
        self.n_obs_steps = int(getattr(self.cfg, "n_obs_steps", 1) or 1)
        # A policy with an observation history must see every step, as lerobot's select_action does: it is
        # asked each step (replan 1) and answers from its own queue, predicting a new chunk only when empty.
        self._replan_inside = replan if self.n_obs_steps > 1 else 0
        if self._replan_inside:
            replan = 1
        self._queue: deque = deque()
        self.spec = PolicySpec(
            family,
            name,
            chunk_size=chunk,
            replan_steps=replan,
            cameras=cams,
            image_size=image_size,
            batched=self.n_obs_steps == 1 and not self._ensemble,
            flip_180=self.conventions.flips,
            observes_objects=self._objects,
            action_dim=self._action_dim,
            training=lerobot_checkpoint.training_cells(config.path),
        )
        self._history: deque = deque(maxlen=self.n_obs_steps)
        self._rng: tuple | None = None  # this instance's generator states since its episode's seed (_own_rng)
        # flow matching (pi0, pi0.5, SmolVLA): the x_1 noise of one query, drawn per row (_query_noise)
        model = getattr(self.policy, "model", None)
        flow = callable(getattr(model, "sample_actions", None)) and hasattr(self.cfg, "max_action_dim")
        self._noise_shape = (int(self.cfg.chunk_size), int(self.cfg.max_action_dim)) if flow else None
        self.pads_batches = self.spec.batched  # act(..., pad_to=N): see interface.act_padded

    def _fail(self, what: str, err: BaseException) -> PolicyError:
        detail = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        return PolicyError(f"policy {self._name}: cannot load {what} from {self.config.path!r}: {detail}")

    def _load(self) -> None:
        import torch

        path, rev = self.config.path, self.config.revision
        local = Path(path).expanduser()
        if local.exists():
            if not (local / "config.json").is_file():
                raise PolicyError(
                    f"policy {self._name}: {str(local)!r} has no config.json; point at the "
                    "pretrained_model directory of a LeRobot checkpoint"
                )
            path = str(local)
        elif path.startswith(("/", ".", "~")) or path.count("/") > 1:
            raise PolicyError(
                f"policy {self._name}: no such checkpoint directory {path!r} (and it is not a Hub "
                "id of the form org/name)"
            )
        with one_package_scan():  # import only this policy's lerobot subpackage (start-up; lerobot_import.py)
            policy_package(local_type(local) if local.exists() else None)
            from lerobot.configs.policies import PreTrainedConfig
            from lerobot.policies.factory import get_policy_class, make_pre_post_processors
        try:
            cfg = PreTrainedConfig.from_pretrained(path, revision=rev)
        except Exception as e:
            # `checkpoints/act_humn` beside `checkpoints/act_human`: a typo of a local path, not a Hub id
            near = _near_local_dir(local)
            if near is not None:
                raise PolicyError(
                    f"policy {self._name}: no checkpoint directory {path!r} (nor a Hub id {path!r}"
                    f"{' in the local cache' if _offline() else ''}); did you mean '{near}'?"
                ) from None
            from huggingface_hub.errors import LocalEntryNotFoundError  # lazy: only on this error

            if _offline() and isinstance(e, LocalEntryNotFoundError):  # the Hub's own text adds nothing here
                fetch = f"hf download {path}" + (f" --revision {rev}" if rev else "")
                raise PolicyError(
                    f"policy {self._name}: {path!r} is not in the local cache and HF_HUB_OFFLINE is set; fetch "
                    f"it once online ({fetch}) or pass a local pretrained_model directory"
                ) from None
            raise self._fail("the policy config", e) from None
        cfg.device = self.config.device
        overrides: dict = {"device_processor": {"device": self.config.device}}
        if self.config.vlm:
            if not hasattr(cfg, "vlm_model_name"):
                raise ConfigError(
                    f"policy {self._name}: vlm= applies to VLM-backed policies (e.g. smolvla), not {cfg.type!r}"
                )
            cfg.vlm_model_name = self.config.vlm
        tokenizer = self.config.tokenizer or self.config.vlm
        if tokenizer and has_step(path, rev, "tokenizer_processor"):
            overrides["tokenizer_processor"] = {"tokenizer_name": tokenizer}
        try:
            policy_cls = get_policy_class(cfg.type)
            # random init on the target device before the weights load over it: a VLA's CPU init takes minutes
            with torch.device(self.config.device), _sizes(path):
                policy = policy_cls.from_pretrained(path, config=cfg, revision=rev)
        except Exception as e:
            raise self._fail(f"the {cfg.type!r} weights", e) from None
        policy.eval()
        try:
            pre, post = make_pre_post_processors(
                cfg,
                pretrained_path=path,
                pretrained_revision=rev,
                preprocessor_overrides=overrides,
            )
        except Exception as e:
            raise PolicyError(
                f"policy {self._name}: cannot load policy_preprocessor/policy_postprocessor from "
                f"{path!r} ({type(e).__name__}: {str(e)[:200]}); checkpoints saved before lerobot 0.4 "
                "need lerobot's migrate_policy_normalization first"
            ) from None
        self._adopt(cfg, policy, pre, post, lambda step: has_step(path, rev, step))

    def _adopt(self, cfg, policy, pre, post, saved_step) -> None:
        """Take a loaded policy and its processors, after checking its features against the scene family's;
        ``saved_step(name)``: whether the preprocessor holds the step registered as (or with class path) ``name``."""
        import torch

        self.cfg, self.policy, self.pre, self.post, self._torch = cfg, policy, pre, post, torch
        action = cfg.action_feature
        env = self.config.env_spec
        if action is None or tuple(action.shape) != (self._action_dim,):
            got = None if action is None else tuple(action.shape)
            what = (
                f"scene family {env.name} takes ({self._action_dim},): {env.layout.split('action: ')[-1]}"
                if env is not None
                else f"indgen's tabletop scenes take ({ACTION_DIM},) delta-EEF actions (OSC_POSE)"
            )
            raise PolicyError(f"policy {self._name}: checkpoint outputs actions of shape {got}; {what}")
        state = cfg.robot_state_feature
        if state is not None and tuple(state.shape) != (self._state_dim,):
            what = env.layout.split(";")[0] if env is not None else "eef pos + axis-angle + gripper qpos"
            raise PolicyError(
                f"policy {self._name}: checkpoint expects observation.state of shape {tuple(state.shape)}; "
                f"ours is ({self._state_dim},) = {what}"
            )
        self._objects = cfg.env_state_feature is not None and saved_step(OBJECT_STEP_CLASS)
        if self._objects and tuple(cfg.env_state_feature.shape) != (OBJECT_DIM,):
            raise PolicyError(
                f"policy {self._name}: checkpoint marks observation.environment_state as object poses but "
                f"its shape is {tuple(cfg.env_state_feature.shape)}, not ({OBJECT_DIM},); retrain it"
            )
        if cfg.env_state_feature is not None and not self._objects and not saved_step(PROPRIO_STEP_CLASS):
            raise PolicyError(
                f"policy {self._name}: checkpoint reads observation.environment_state (privileged "
                "simulator state), which learned policies never get here"
            )

    def _chunking(self) -> tuple[int, int]:
        cfg = self.cfg
        n_action = getattr(cfg, "n_action_steps", None)
        if cfg.type == "diffusion":  # generate_actions returns n_action_steps actions
            chunk = int(n_action)
        else:
            chunk = int(getattr(cfg, "chunk_size", None) or n_action or 1)
        replan = self.config.replan_steps or int(n_action or chunk)
        if replan > chunk:
            raise ConfigError(f"policy {self._name}: replan={replan} exceeds the chunk of {chunk} actions")
        return chunk, replan

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._history.clear()
        self._queue.clear()
        self.policy.reset()
        self._rng = None
        if seed is not None:  # flow-matching / diffusion noise: drawn from this episode's own stream
            with self._own_rng():
                self._torch.manual_seed(int(seed))

    @contextlib.contextmanager
    def _own_rng(self):
        """Run with torch's default CPU and CUDA generators set to this instance's states, kept afterwards and the
        global ones restored: lerobot draws its noise from the global generators, which every instance in the
        process shares (one per environment, acting from threads), so an episode's noise would otherwise depend on
        when the other environments' episodes reset and act. (On MPS its generator stays the shared one.)"""
        torch = self._torch
        device = torch.device(self.config.device)
        cuda = [device.index or 0] if device.type == "cuda" else []
        with _RNG_LOCK, torch.random.fork_rng(devices=cuda):
            if self._rng is not None:
                torch.set_rng_state(self._rng[0])
                if cuda:
                    torch.cuda.set_rng_state(self._rng[1], cuda[0])
            yield
            self._rng = (torch.get_rng_state(), *(torch.cuda.get_rng_state(cuda[0]) for _ in cuda))

    def to_batch(self, observations: Sequence[Observation], pad_to: int | None = None) -> dict:
        """Our observations -> lerobot's raw batch (float CHW images in [0, 1] at the declared size, state, task).

        Images cross to the policy's device once, as uint8 (a quarter of the float bytes), and are flipped,
        scaled and resized there in one batched call per camera. ``pad_to``: repeat the first row up to that
        many rows after this per-row work (``interface.act_padded``; equal to padding the observations).
        """
        torch = self._torch
        import torch.nn.functional as F  # noqa: N812

        device = torch.device(self.config.device)
        rows = len(observations)
        pad = max(0, (pad_to or rows) - rows)
        only_flip = all(isinstance(s, Flip180) for s in self.conventions.images.steps)

        def padded(t):
            return torch.cat([t, t[:1].expand(pad, *t.shape[1:])]) if pad else t

        batch: dict = {}
        for feat, cam, (_, h, w) in self._cams:
            if cam == ZEROS:
                batch[IMAGE_PREFIX + feat] = torch.zeros((rows + pad, 3, h, w), device=device)
                continue
            try:
                if only_flip:
                    imgs = np.stack([obs.images[cam] for obs in observations])
                else:
                    imgs = np.stack([self.conventions.images(obs.images[cam]) for obs in observations])
            except KeyError:
                raise PolicyError(
                    f"policy {self._name} needs camera {cam!r}; observation has "
                    f"{sorted(observations[0].images)}"
                ) from None
            t = torch.from_numpy(imgs).to(device, non_blocking=True)
            if only_flip and self.conventions.flips:
                t = t.flip(1, 2)
            t = t.permute(0, 3, 1, 2).float().div_(255.0)
            if t.shape[-2:] != (h, w):
                t = F.interpolate(
                    t, size=(h, w), mode="bilinear", align_corners=False, antialias=True
                ).clamp_(0, 1)
            batch[IMAGE_PREFIX + feat] = padded(t)
        if self.cfg.robot_state_feature is not None:
            state = np.stack([o.state for o in observations]).astype(np.float32)
            if self._state_in is not None:  # our state order -> the one the checkpoint was trained on
                state = np.ascontiguousarray(self._state_in(state))
            batch["observation.state"] = padded(torch.from_numpy(state).to(device, non_blocking=True))
        if self._objects:
            if any(o.objects is None for o in observations):
                raise PolicyError(f"policy {self._name} reads object poses; the observation carries none")
            objects = np.stack([o.objects for o in observations]).astype(np.float32)
            batch["observation.environment_state"] = padded(torch.from_numpy(objects).to(device))
        tasks = [o.instruction for o in observations]
        batch["task"] = tasks + tasks[:1] * pad
        return batch

    def _with_history(self, batch: dict) -> dict:
        """Stack the last n_obs_steps preprocessed observations along dim 1 (lerobot's populate_queues)."""
        keys = [IMAGE_PREFIX + feat for feat, _, _ in self._cams]
        keys += ["observation.state"] if "observation.state" in batch else []
        if self._history and next(iter(self._history))[keys[0]].shape[0] != batch[keys[0]].shape[0]:
            self._history.clear()
        if not self._history:
            for _ in range(self.n_obs_steps - 1):
                self._history.append({k: batch[k] for k in keys})
        self._history.append({k: batch[k] for k in keys})
        out = dict(batch)
        for k in keys:
            out[k] = self._torch.stack([h[k] for h in self._history], dim=1)
        return out

    def act(self, observations: Sequence[Observation], pad_to: int | None = None) -> np.ndarray:
        """(B, T, 7) chunks. ``pad_to`` (batched policies): the forward runs on that many rows, the first
        observation's repeated after pre-processing, and only the real rows come back (``act_padded``)."""
        if pad_to is not None and self.spec.batched:
            return self._predict(observations, pad_to)
        if self._ensemble:  # lerobot's select_action: predict a chunk, fold it into the ensemble, one action
            with self._torch.inference_mode():
                with self._autocast():
                    with self._own_rng():
                        action = self.post(self.policy.select_action(self.pre(self.to_batch(observations))))
            chunk = action.detach().to("cpu", self._torch.float32).numpy()[:, None]
            return self._to_scene(validate_chunk(chunk, len(observations), self._name, self._action_dim))
        if not self._replan_inside:
            return self._predict(observations)
        # history policies (not batched): record this step, replan from the queue like select_action
        if self._queue:
            with self._torch.inference_mode():
                self._with_history(self.pre(self.to_batch(observations)))
        else:
            chunk = self._predict(observations)[0]
            self._queue.extend(chunk[: self._replan_inside])
        out = np.stack(list(self._queue))[None]
        self._queue.popleft()
        return out

    def _predict(self, observations: Sequence[Observation], pad_to: int | None = None) -> np.ndarray:
        torch = self._torch
        with torch.inference_mode():
            batch = self.pre(self.to_batch(observations, pad_to))
            if self.n_obs_steps > 1:
                batch = self._with_history(batch)
            noise = self._query_noise(observations, pad_to)
            try:
                with self._autocast(), self._own_rng():
                    actions = self.policy.predict_action_chunk(
                        batch, **({} if noise is None else {"noise": noise})
                    )
            except Exception as e:
                first = (str(e).strip().splitlines() or [""])[0][:300]
                raise PolicyError(f"policy {self._name} failed to act: {type(e).__name__}: {first}") from e
            if actions.ndim == 2:
                actions = actions[:, None]
            actions = self.post(actions)
        chunk = actions[: len(observations)].detach().to("cpu", torch.float32).numpy()
        return self._to_scene(validate_chunk(chunk, len(observations), self._name, self._action_dim))

    def _query_noise(self, observations: Sequence[Observation], pad_to: int | None):
        """Flow-matching noise for each row from its query's identity (the engine's ``QUERY_KEY``: episode seed,
        steps taken), so a row's actions do not depend on which episodes share its batch or when they reset; padded
        rows repeat the first row's. None (lerobot draws it from this instance's stream) for other policies or
        observations without it. Standard-normal float32, as lerobot's ``sample_noise`` draws it."""
        keys = [o.extras.get(QUERY_KEY) for o in observations]
        if self._noise_shape is None or any(k is None for k in keys):
            return None
        torch = self._torch
        rows = [torch.randn(self._noise_shape, dtype=torch.float32,
                            generator=torch.Generator().manual_seed(episode_seed(seed, "noise", step)))
                for seed, step in keys]  # fmt: skip
        rows += rows[:1] * ((pad_to or len(rows)) - len(rows))
        return torch.stack(rows).to(self.config.device)

    def _to_scene(self, chunk: np.ndarray) -> np.ndarray:
        """The checkpoint's action order -> the scene's (identity on the tabletop families)."""
        return chunk if self._action_out is None else np.ascontiguousarray(self._action_out(chunk))

    def _autocast(self):
        """bf16 autocast when asked (``precision=bf16``); otherwise nothing changes."""
        import contextlib

        if self.config.precision != "bf16":
            return contextlib.nullcontext()
        return self._torch.autocast(self._torch.device(self.config.device).type, dtype=self._torch.bfloat16)

    def close(self) -> None:
        self.policy = self.pre = self.post = None


def _sizes(path: str):
    """lerobot's own sizes, or the reduced ones for a ``build_real_size.py --reduced`` directory."""
    return lerobot_variants.reduced() if lerobot_variants.is_reduced(path) else contextlib.nullcontext()


def _offline() -> bool:
    import os

    return os.environ.get("HF_HUB_OFFLINE", "").lower() in ("1", "true", "yes", "on")


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", family: str = "lerobot",
    env_spec: EnvSpec | None = None,
):  # fmt: skip
    """``lerobot:<hub id or dir>[?cameras=..&flip=0|1&replan=N&revision=REV&vlm=DIR&tokenizer=DIR&precision=bf16&compile=MODE]``.

    LeRobot policies are plain PyTorch modules loaded from safetensors: no Hub code is executed, so
    ``trust_remote_code`` has nothing to enable here. ``env_spec``: the scene family's contract, which picks
    lerobot's layout there (RoboCasa365: ``layouts.LEROBOT_ROBOCASA``).
    """
    return LeRobotPolicy(parsed.spec, make_config(parsed, options, device, env_spec), family=family)


def preview(parsed, options, *, device: str = "cpu", env_spec: EnvSpec | None = None) -> ScenePreview | None:
    """The scene this spec's checkpoint will ask for, read from its files before it loads (the registry's
    ``preview_policy``; ``lerobot_checkpoint.preview``)."""
    return lerobot_checkpoint.preview(parsed, options, device=device, env_spec=env_spec)
