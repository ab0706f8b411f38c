"""``groot:tcp://HOST:PORT`` — Isaac-GR00T's ZMQ REQ/REP inference service (N1.5 and N1.6 message shapes).

Wire (``gr00t/eval/service.py`` N1.5, ``gr00t/policy/server_client.py`` N1.6): msgpack with ndarrays as
``{"__ndarray_class__": True, "as_npy": np.save bytes}``; requests ``{"endpoint", "data"[, "api_token"]}``;
errors come back as ``{"error": msg}``. N1.5 ``get_action`` takes flat unbatched keys (LIBERO example
``examples/Libero/eval/run_libero_eval.py``: ``video.image`` (1,H,W,3), ``state.x`` (1,1) … ``state.gripper``
(1,2), ``annotation.human.action.task_description`` [str]) and returns ``action.*`` (16, D). N1.6 (server run
with ``--use-sim-policy-wrapper``) takes ``{"observation": flat batched keys (B,1,…), "options"}`` and returns
``[action, info]`` with ``action.*`` (B, 16, D); it also has ``reset`` and ``get_modality_config``.

Gripper: GR00T's LIBERO checkpoints output [0, 1] with 1 = open (the RLDS convention), so upstream inverts:
N1.5 ``examples/Libero/eval/utils.py:normalize_gripper_action`` computes ``sign(1 - 2x)``, N1.6+
``gr00t/eval/sim/LIBERO/libero_env.py`` ``normalize_gripper_action`` (``sign(2x - 1)``) then
``invert_gripper_action`` (x -1). Both are our ``gripper=01inv`` (the default): 0.9 -> -1 (open).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from indgen_vla.errors import ConfigError, PolicyConnectionError, PolicyError
from indgen_vla.interface import ACTION_DIM, CAMERAS, Observation, PolicySpec, validate_chunk
from policy_wrappers.image_tools import GRIPPER_MODES, convert_gripper, flip_180, resize_with_pad
from policy_wrappers.msgpack_numpy import groot_packb, groot_unpackb

LIBERO_STATE = (
    ("x", 0, 1),
    ("y", 1, 2),
    ("z", 2, 3),
    ("roll", 3, 4),
    ("pitch", 4, 5),
    ("yaw", 5, 6),
    ("gripper", 6, 8),
)
LIBERO_ACTION = ("x", "y", "z", "roll", "pitch", "yaw", "gripper")


@dataclass(frozen=True)
class GrootConfig:
    """Endpoint, API version and the modality map from our Observation (defaults: GR00T's LIBERO example)."""

    url: str
    api: str = "n1.6"
    api_token: str | None = None
    video: tuple[tuple[str, str], ...] = (("image", "agentview"), ("wrist_image", "wrist"))
    state: tuple[tuple[str, int, int], ...] = LIBERO_STATE
    action: tuple[str, ...] = LIBERO_ACTION
    language_key: str = "annotation.human.action.task_description"
    chunk_size: int = 16
    replan_steps: int = 8
    render_size: int = 256
    image_size: int | None = None  # resize-with-pad before sending; None sends the render as is
    flip_180: bool = True
    gripper: str = "01inv"  # upstream LIBERO eval: [0, 1] (1 = open) -> sign(1 - 2x)
    timeout_s: float = 60.0
    connect_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if self.api not in ("n1.5", "n1.6"):
            raise ConfigError(f"groot {self.url}: api must be n1.5 or n1.6, got {self.api!r}")
        if self.gripper not in GRIPPER_MODES:
            raise ConfigError(f"groot {self.url}: gripper must be one of {GRIPPER_MODES}")
        bad = [cam for _, cam in self.video if cam not in CAMERAS]
        if bad or not self.video:
            raise ConfigError(
                f"groot {self.url}: video map needs cameras from {list(CAMERAS)}, got {bad or 'none'}"
            )
        if sum(hi - lo for _, lo, hi in self.state) > 8 or any(
            not 0 <= lo < hi <= 8 for _, lo, hi in self.state
        ):
            raise ConfigError(f"groot {self.url}: state slices must lie within our 8-d state")


class GrootPolicy:
    """ZMQ client for one GR00T inference server (N1.6 sends the whole batch in one request)."""

    def __init__(self, name: str, config: GrootConfig):
        import zmq

        self.config, self._zmq = config, zmq
        cams = tuple(c for c in CAMERAS if c in {cam for _, cam in config.video})
        self.spec = PolicySpec(
            "groot",
            name,
            chunk_size=config.chunk_size,
            replan_steps=config.replan_steps,
            cameras=cams,
            image_size=(config.render_size,) * 2,
            batched=config.api == "n1.6",
            flip_180=config.flip_180,
        )
        self._ctx = zmq.Context()
        self._sock = None
        self._language_key = config.language_key
        self.modality_config: dict = {}
        self._handshake()

    def _socket(self):
        if self._sock is None:
            self._sock = self._ctx.socket(self._zmq.REQ)
            self._sock.setsockopt(self._zmq.LINGER, 0)
            self._sock.connect(self.config.url)
        return self._sock

    def _drop(self) -> None:
        if self._sock is not None:
            self._sock.close(linger=0)
        self._sock = None

    def call(self, endpoint: str, data=None, requires_input: bool = True, timeout_s: float | None = None):
        """One request/reply. A timeout or ZMQ error raises PolicyConnectionError and rebuilds the REQ socket
        (so the next call reconnects); an error reply from the server raises PolicyError."""
        request: dict = {"endpoint": endpoint}
        if requires_input:
            request["data"] = data
        if self.config.api_token:
            request["api_token"] = self.config.api_token
        timeout = self.config.timeout_s if timeout_s is None else timeout_s
        try:
            sock = self._socket()
            sock.send(groot_packb(request))
            if not sock.poll(int(timeout * 1000)):
                self._drop()
                raise PolicyConnectionError(
                    f"policy {self.spec.name}: no reply from {self.config.url} to {endpoint!r} within "
                    f"{timeout:g}s; is the GR00T server running?"
                )
            message = sock.recv()
        except self._zmq.ZMQError as e:
            self._drop()
            raise PolicyConnectionError(
                f"policy {self.spec.name}: ZMQ error talking to {self.config.url}: {e}"
            ) from None
        if message == b"ERROR":
            raise PolicyError(f"policy {self.spec.name}: server error (is it the right GR00T policy server?)")
        try:
            response = groot_unpackb(message)
        except Exception as e:
            raise PolicyError(
                f"policy {self.spec.name}: undecodable reply ({type(e).__name__}: {e})"
            ) from None
        if isinstance(response, dict) and "error" in response:
            first = (str(response["error"]).strip().splitlines() or [""])[0][:300]
            hint = (
                " (if this is an N1.5 server, add ?api=n1.5)"
                if endpoint == "get_action" and self.config.api == "n1.6"
                else ""
            )
            raise PolicyError(f"policy {self.spec.name}: server error: {first}{hint}")
        return response

    def _handshake(self) -> None:
        try:
            self.call("ping", requires_input=False, timeout_s=self.config.connect_timeout_s)
        except PolicyError:
            self.close()
            raise
        try:
            config = self.call(
                "get_modality_config", requires_input=False, timeout_s=self.config.connect_timeout_s
            )
        except PolicyError:
            config = {}
        self.modality_config = config if isinstance(config, dict) else {}
        self._check_modalities()

    def _check_modalities(self) -> None:
        """Compare our modality map with what the server declares (when it declares anything)."""

        def keys(modality: str) -> list[str]:
            entry = self.modality_config.get(modality)
            return (
                [str(k).split(".", 1)[-1] for k in (entry or {}).get("modality_keys", [])]
                if isinstance(entry, dict)
                else []
            )

        for modality, ours in (
            ("video", [k for k, _ in self.config.video]),
            ("state", [k for k, _, _ in self.config.state]),
        ):
            theirs = keys(modality)
            missing = sorted(set(theirs) - set(ours))
            if theirs and missing:
                self.close()
                raise PolicyError(
                    f"policy {self.spec.name}: server expects {modality} keys {theirs}; our map gives "
                    f"{ours} (set ?{modality}=... to map {missing})"
                )
        lang = (
            (self.modality_config.get("language") or {})
            if isinstance(self.modality_config.get("language"), dict)
            else {}
        )
        if lang.get("modality_keys") and self._language_key not in lang["modality_keys"]:
            self._language_key = str(lang["modality_keys"][0])

    def reset(self, instruction: str, seed: int | None = None) -> None:
        if self.config.api == "n1.6":
            self.call("reset", {"options": None})

    def _images(self, obs: Observation, cam: str) -> np.ndarray:
        if cam not in obs.images:
            raise PolicyError(
                f"policy {self.spec.name} needs camera {cam!r}; observation has {sorted(obs.images)}"
            )
        img = flip_180(obs.images[cam]) if self.config.flip_180 else obs.images[cam]
        size = self.config.image_size
        return resize_with_pad(img, size, size) if size else np.ascontiguousarray(img)

    def make_observation(self, observations: Sequence[Observation]) -> dict:
        """Flat GR00T keys; N1.5: one unbatched observation (T=1 leading), N1.6: (B, T=1, ...)."""
        batched = self.config.api == "n1.6"
        out: dict = {}
        for key, cam in self.config.video:
            frames = np.stack([self._images(o, cam) for o in observations])[:, None]  # (B, 1, H, W, 3)
            out[f"video.{key}"] = frames if batched else frames[0]
        for key, lo, hi in self.config.state:
            vals = np.stack([o.state[lo:hi] for o in observations])[:, None]  # (B, 1, D)
            out[f"state.{key}"] = vals.astype(np.float32) if batched else vals[0].astype(np.float64)
        out[self._language_key] = [o.instruction for o in observations]
        return out

    def _parse_actions(self, action: dict, batch: int) -> np.ndarray:
        if not isinstance(action, dict):
            raise PolicyError(f"policy {self.spec.name}: action reply is {type(action).__name__}, not a dict")
        parts = []
        for key in self.config.action:
            name = f"action.{key}"
            value = action.get(name, action.get(key))
            if value is None:
                raise PolicyError(f"policy {self.spec.name}: reply lacks {name!r} (got {sorted(action)})")
            arr = np.asarray(value, dtype=np.float32)
            if arr.ndim == 1:
                arr = arr[:, None]
            if arr.ndim == 2:
                arr = arr[None]
            if arr.ndim != 3 or arr.shape[0] != batch:
                raise PolicyError(
                    f"policy {self.spec.name}: {name} has shape {np.shape(value)}; expected (T, D) or (B, T, D)"
                )
            parts.append(arr)
        if len({p.shape[1] for p in parts}) != 1:
            raise PolicyError(
                f"policy {self.spec.name}: action keys disagree on the horizon: {[p.shape for p in parts]}"
            )
        chunk = np.concatenate(parts, axis=-1)
        if chunk.shape[-1] != ACTION_DIM or chunk.shape[1] < self.spec.replan_steps:
            raise PolicyError(
                f"policy {self.spec.name} returned actions of shape {chunk.shape}; expected "
                f"({batch}, >={self.spec.replan_steps}, {ACTION_DIM})"
            )
        return chunk[:, : self.spec.chunk_size]

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        if self.config.api == "n1.6":
            reply = self.call(
                "get_action", {"observation": self.make_observation(observations), "options": None}
            )
            if not isinstance(reply, list | tuple) or len(reply) != 2:
                raise PolicyError(
                    f"policy {self.spec.name}: N1.6 get_action must return [action, info], got "
                    f"{type(reply).__name__}; is this an N1.5 server? (use ?api=n1.5)"
                )
            chunk = self._parse_actions(reply[0], len(observations))
        else:
            chunks = []
            for obs in observations:
                reply = self.call("get_action", self.make_observation([obs]))
                if isinstance(reply, list | tuple):
                    raise PolicyError(
                        f"policy {self.spec.name}: got [action, info]; this is an N1.6 server (use ?api=n1.6)"
                    )
                chunks.append(self._parse_actions(reply, 1)[0])
            chunk = np.stack(chunks)
        chunk = validate_chunk(chunk, len(observations), self.spec.name)
        return convert_gripper(chunk, self.config.gripper)

    def close(self) -> None:
        self._drop()
        self._ctx.term()


def _pairs(text: str | None, default):
    if not text:
        return default
    out = []
    for item in text.split(","):
        key, sep, cam = item.partition(":")
        if not sep:
            raise ConfigError(
                f"bad groot video mapping {item!r}; write video=image:agentview,wrist_image:wrist"
            )
        out.append((key.strip(), cam.strip()))
    return tuple(out)


def load(parsed, options, *, trust_remote_code: bool = False, device: str = "cpu") -> GrootPolicy:
    """``groot:tcp://HOST:PORT[?api=n1.5|n1.6&api_token=&video=key:cam,..&replan=&chunk=&size=&flip=&gripper=]``."""
    from policy_wrappers.registry import check_url, join_url

    _, host, port = check_url(parsed.spec, parsed.target, ("tcp",), 5555)
    api = options.choice("api", ("n1.5", "n1.6"), "n1.6")
    chunk = options.int("chunk", 16)
    config = GrootConfig(
        url=join_url("tcp", host, port),
        api=api,
        api_token=options.str("api_token"),
        video=_pairs(options.str("video"), GrootConfig.video),
        language_key=options.str("lang_key", GrootConfig.language_key),
        chunk_size=chunk,
        replan_steps=options.int("replan", 1 if api == "n1.5" else min(8, chunk)),
        render_size=options.int("render", 256),
        image_size=options.int("size"),
        flip_180=options.bool("flip", True),
        gripper=options.choice("gripper", GRIPPER_MODES, "01inv"),
        timeout_s=options.float("timeout", 60.0),
        connect_timeout_s=options.float("connect_timeout", 10.0),
    )
    return GrootPolicy(parsed.spec, config)
