"""Serve a UniVLA or RynnVLA-002 LIBERO checkpoint to the ``univla:`` / ``rynnvla:`` specs (openpi's websocket).

Neither upstream ships a server; both evaluate LIBERO in-process. This script runs INSIDE the model's own
environment (its torch, transformers, flash-attn and upstream code; ``pip install msgpack websockets`` there),
imports the upstream inference and serves it with ``policy_wrappers.serve.PolicyServer`` (this repository is put
on ``sys.path`` from the script's own location). Everything a model does between our request and the
simulator's action that its upstream eval does outside the model call is here, in one place per model:

UniVLA (baaivision/UniVLA, ``reference/RoboVLMs/eval/libero``): ``evaluate_libero_emu.py:prepare_observation``
sends ``{full_image, wrist_image, state}`` (both flipped 180° at 256) and the task language to
``model_wrapper_emu.py:EmuVLAModel.step``, which resizes to 200, decodes the 10-step FAST chunk, de-normalises it
and binarises the gripper; the eval executes all 10. We call that same ``step``.

RynnVLA-002 (``rynnvla-002/eval_solver_libero_continous_w_state.py:val_libero``): both cameras flipped at 256
(``libero_util/libero_utils.py:get_libero_image``), the raw 8-d state (the ItemProcessor normalises it) and the
previous frames go to ``libero_util/Chameleon_utils.py:get_action_Chameleon_dis_awm_ck_continous_action`` with
``his_2_third_view_wrist_w_state``; its chunk is de-normalised with ``Solver.unnorm_action_min_max`` (below:
``ACTION_MIN``/``ACTION_MAX``, gripper left continuous) and executed whole. Upstream's history frame is the one
rendered one env step before the query (none at an episode's first query); the ``rynnvla:`` client declares
``history_steps=1``, so the engine renders that step and the request carries it (``indgen/history/...`` keys). A
client that sends none (a plain openpi client) gets the previous *query's* frames instead (``time_horizon`` steps
earlier; said once in the log): kept per connection (per simulator), cleared at each episode start (the
client's ``indgen/reset`` hint).

Examples (docs/policies.md has the full commands):
  cd UniVLA/reference/RoboVLMs && PYTHONPATH=../Emu3:eval/libero python /path/indgen-vla/scripts/serve/libero_vla.py \\
      univla --ckpt UNIVLA_LIBERO_VIDEO_BS192_8K --vq-hub Emu3-Base --vision-hub Emu3-VisionTokenizer --fast pretrain/fast
  cd RynnVLA-002/rynnvla-002/evals_libero && PYTHONPATH=..:../.. python /path/indgen-vla/scripts/serve/libero_vla.py \\
      rynnvla --ckpt VLA_model_256/libero_object --suite libero_object --tokenizer ../ckpts/<Lumina-mGPT-7B-768 snapshot>
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this repository, for the protocol

from indgen_vla.core.protocol.interface import Observation, PolicySpec  # noqa: E402
from policy_wrappers.openpi import HISTORY_PREFIX  # noqa: E402
from policy_wrappers.serve import PolicyServer  # noqa: E402

log = logging.getLogger("libero_vla")

CAMERAS = ("agentview", "wrist")
RENDER = 256  # get_libero_env(task, resolution=256) in both evals
UNIVLA_CHUNK = 10  # EmuVLAModel.predict_action_frames
# RynnVLA-002: evals_libero/eval_<suite>_*_continous.sh --time_horizon, and the history setting of every released
# VLA_model_256 checkpoint (his_2: the previous frame of both cameras, then the current ones; w_state: the state)
RYNNVLA_HORIZON = {"libero_spatial": 10, "libero_object": 5, "libero_goal": 5, "libero_10": 10}
RYNNVLA_HISTORY = "his_2_third_view_wrist_w_state"
# eval_solver_libero_continous_w_state.py:Solver.unnorm_action_min_max (the no-noops LIBERO action bounds)
ACTION_MIN = np.array([-0.9375, -0.9375, -0.9375, -0.24214286, -0.375, -0.36428571, -1.0])
ACTION_MAX = np.array([0.9375, 0.9375, 0.9375, 0.34821429, 0.375, 0.375, 1.0])


def rynnvla_unnormalize(chunk: np.ndarray) -> np.ndarray:
    """[-1, 1] model actions -> LIBERO's: ``(a + 1) / 2 * (max - min + 1e-8) + min`` per row, first 7 dims."""
    a = np.asarray(chunk, dtype=np.float64)[..., :7]
    return (a + 1) / 2 * (ACTION_MAX - ACTION_MIN + 1e-8) + ACTION_MIN


def server_spec(model: str, chunk: int, target: str) -> PolicySpec:
    """What the server announces in its metadata (the client checks family and chunk)."""
    return PolicySpec(
        model, f"{model}-server:{target}", chunk_size=chunk, replan_steps=chunk, cameras=CAMERAS,
        image_size=(RENDER, RENDER), flip_180=True,
    )  # fmt: skip


def _cameras(images: dict[str, np.ndarray], prefix: str = "") -> tuple[np.ndarray, np.ndarray]:
    missing = [c for c in CAMERAS if c not in images]
    if missing:
        raise ValueError(
            f"request lacks {'history ' if prefix else ''}camera(s) {missing}; send {prefix}observation/image and "
            f"{prefix}observation/wrist_image"
        )
    return images["agentview"], images["wrist"]


class UniVLASession:
    """``EmuVLAModel``'s ``reset``/``step`` as a policy; ``step`` does resize, decoding, de-norm and gripper."""

    def __init__(self, model, spec: PolicySpec):
        self.model, self.spec = model, spec

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self.model.reset()

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        (obs,) = observations
        full, wrist = _cameras(obs.images)
        observation = {"full_image": full, "wrist_image": wrist, "state": np.asarray(obs.state, np.float64)}
        actions = np.asarray(self.model.step(observation, obs.instruction), dtype=np.float32)
        return actions[None]

    def close(self) -> None:
        pass


class RynnVLASession:
    """One simulator's RynnVLA-002 episode: the step-before frames as history, de-normalised chunks.

    ``infer(cur_img, cur_wrist, task, his_img, his_wrist, state)`` is the upstream call (PIL images, lists of
    earlier PIL frames, the raw 8-d state) returning the normalised (T, >=7) chunk. The history is the
    request's (the frames of the env step before the query) when it has one; otherwise, for clients that send
    none, the previous query's frames (empty at an episode's first query, as upstream's).
    """

    def __init__(self, infer: Callable, spec: PolicySpec):
        self.infer, self.spec = infer, spec
        self.his_img: list = []
        self.his_wrist: list = []

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self.his_img, self.his_wrist = [], []

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        (obs,) = observations
        cur, wrist = (_pil(img) for img in _cameras(obs.images))
        if obs.history:  # eval_solver_libero_continous_w_state.py:val_libero, his_img[-1:]: the step before
            his_img, his_wrist = ([_pil(img)] for img in _cameras(obs.history[-1], HISTORY_PREFIX))
        else:
            his_img, his_wrist = self.his_img[-1:], self.his_wrist[-1:]
            if his_img:
                _warn_query_history()
        state = np.asarray(obs.state, dtype=np.float64)
        out = self.infer(cur, wrist, obs.instruction, his_img, his_wrist, state)
        chunk = np.asarray(out.float().cpu().numpy() if hasattr(out, "cpu") else out, dtype=np.float64)
        if chunk.ndim != 2 or chunk.shape[0] != self.spec.chunk_size or chunk.shape[1] < 7:
            raise ValueError(
                f"the model returned actions of shape {chunk.shape}; expected ({self.spec.chunk_size}, 7): "
                "is --suite the checkpoint's suite?"
            )
        self.his_img, self.his_wrist = [cur], [wrist]
        return rynnvla_unnormalize(chunk)[None].astype(np.float32)

    def close(self) -> None:
        pass


def _pil(image: np.ndarray):
    from PIL import Image

    return Image.fromarray(np.ascontiguousarray(image))


@functools.cache
def _warn_query_history() -> None:
    """Say once per server that a client sends no history (upstream's is the step before, not the query before)."""
    log.warning(
        "a client sent no history frames: RynnVLA-002 gets the previous query's frames (time_horizon steps "
        "earlier), not the previous env step's as upstream; use the rynnvla: client (history_steps=1)"
    )


def load_univla(args) -> Callable[[], UniVLASession]:
    """Build upstream's ``EmuVLAModel`` with our paths (upstream hard-codes its cluster's FAST and stats paths)."""
    import queue

    import torch
    from emu3.mllm import Emu3MoE, Emu3Processor, Emu3Tokenizer
    from model_wrapper_emu import EmuVLAModel
    from transformers import AutoImageProcessor, AutoModel, AutoProcessor

    class Model(EmuVLAModel):
        @staticmethod
        def load_dataset_stat():  # upstream reads a file it never uses (unormalize_action has the bounds)
            return {}

        def init_config(self, device):
            self.model = Emu3MoE.from_pretrained(
                self.emu_hub, torch_dtype=torch.bfloat16, attn_implementation="flash_attention_2",
                trust_remote_code=True,
            ).to(device).eval()  # fmt: skip
            self.tokenizer = Emu3Tokenizer.from_pretrained(
                self.vq_hub, model_max_length=self.model.config.max_position_embeddings, padding_side="right",
                use_fast=False,
            )  # fmt: skip
            self.image_processor = AutoImageProcessor.from_pretrained(self.vision_hub, trust_remote_code=True)
            self.image_tokenizer = (
                AutoModel.from_pretrained(self.vision_hub, trust_remote_code=True).to(device).eval()
            )
            self.processor = Emu3Processor(self.image_processor, self.image_tokenizer, self.tokenizer)
            self.action_tokenizer = AutoProcessor.from_pretrained(args.fast, trust_remote_code=True)
            self.rgb_list, self.hand_rgb_list, self.action_hist_list = [], [], []
            self.rollout_step_counter = 0
            self.vision_queue = queue.Queue(maxsize=self.window_size)
            self.vision_gripper_queue = queue.Queue(maxsize=self.window_size)
            self.action_queue = queue.Queue(maxsize=self.window_size - 1)

    model = Model(
        emu_hub=args.ckpt, vq_hub=args.vq_hub, vision_hub=args.vision_hub, device=torch.device("cuda")
    )
    if model.video_mode or model.use_one_step or model.predict_action_frames != UNIVLA_CHUNK:
        raise SystemExit(
            "this UniVLA checkout's EmuVLAModel differs from the one read (video_mode off, 10 actions)"
        )
    spec = server_spec("univla", UNIVLA_CHUNK, args.ckpt)
    return lambda: UniVLASession(model, spec)


def load_rynnvla(args) -> Callable[[], RynnVLASession]:
    """Upstream's model class, ItemProcessor and continuous-action call, loaded as its LIBERO eval loads them."""
    import torch
    from data.pre_tokenize_action_state import ItemProcessor
    from libero_util.Chameleon_utils import get_action_Chameleon_dis_awm_ck_continous_action as get_action
    from model import ChameleonXLLMXForConditionalGeneration_ck_action_head as Model

    horizon = RYNNVLA_HORIZON[args.suite]
    model = Model.from_pretrained(
        args.ckpt, action_dim=7, time_horizon=horizon, max_position_embeddings=8192, mask_image_logits=False,
        dropout=0.05, z_loss_weight=1e-5, torch_dtype=torch.bfloat16, device_map="cpu",
    ).to(torch.device("cuda")).eval()  # fmt: skip
    processor = ItemProcessor(target_size=RENDER, tokenizer=args.tokenizer)

    def infer(cur, wrist, task, his_img, his_wrist, state):
        with torch.no_grad():
            return get_action(
                model, cur, wrist, task, processor, his_img, his_wrist, state, [], RYNNVLA_HISTORY, 25
            )

    spec = server_spec("rynnvla", horizon, args.ckpt)
    return functools.partial(RynnVLASession, infer, spec)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=8000)
    parser.add_argument(
        "--api-key", default=None, help="require 'Authorization: Api-Key KEY' (spec ?api_key=)"
    )
    sub = parser.add_subparsers(dest="model", required=True)
    uni = sub.add_parser("univla", help="baaivision/UniVLA LIBERO checkpoint (one for all suites)")
    uni.add_argument("--ckpt", required=True, help="e.g. Yuqi1997/UniVLA UNIVLA_LIBERO_VIDEO_BS192_8K")
    uni.add_argument("--vq-hub", required=True, help="Emu3 tokenizer (BAAI/Emu3-Base)")
    uni.add_argument("--vision-hub", required=True, help="Emu3 vision tokenizer (BAAI/Emu3-VisionTokenizer)")
    uni.add_argument("--fast", required=True, help="UniVLA's FAST action tokenizer (pretrain/fast)")
    rynn = sub.add_parser("rynnvla", help="RynnVLA-002 VLA_model_256 LIBERO checkpoint (one per suite)")
    rynn.add_argument(
        "--ckpt", required=True, help="e.g. Alibaba-DAMO-Academy/RynnVLA-002 VLA_model_256/libero_object"
    )
    rynn.add_argument(
        "--suite", required=True, choices=sorted(RYNNVLA_HORIZON), help="the checkpoint's suite"
    )
    rynn.add_argument(
        "--tokenizer", required=True, help="the Lumina-mGPT-7B-768 snapshot the eval scripts name"
    )
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    import asyncio

    args = parse_args(argv)
    if not 0 <= args.port <= 65535:
        print(f"--port must be in 0..65535, got {args.port}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    session = {"univla": load_univla, "rynnvla": load_rynnvla}[args.model](args)
    first = session()
    server = PolicyServer(
        first, host=args.host, port=args.port, api_key=args.api_key, unflip=False, session=session
    )
    print(
        f"serving {first.spec.name} on ws://{args.host}:{args.port} (spec {args.model}:ws://HOST:{args.port})"
    )
    try:
        asyncio.run(server.run())
    except KeyboardInterrupt:
        pass
    except OSError as e:
        print(f"cannot listen on {args.host}:{args.port}: {e.strerror or e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
