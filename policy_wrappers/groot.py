"""``groot:tcp://HOST:PORT`` — Isaac-GR00T's ZMQ REQ/REP inference service (N1.5 and N1.6 message shapes).

Wire (``gr00t/eval/service.py`` N1.5, ``gr00t/policy/server_client.py`` N1.6): msgpack with ndarrays as
``{"__ndarray_class__": True, "as_npy": np.save bytes}`` (N1.5 trees up to July 2025 frame with ``torch.save``
instead: ``?serializer=torch``, ``torch_wire.py``); requests ``{"endpoint", "data"[, "api_token"]}``;
errors come back as ``{"error": msg}``. N1.5 ``get_action`` takes flat unbatched keys (LIBERO example
``examples/Libero/eval/run_libero_eval.py``: ``video.image`` (1,H,W,3), ``state.x`` (1,1) … ``state.gripper``
(1,2), ``annotation.human.action.task_description`` [str]) and returns ``action.*`` (16, D). N1.6 (server run
with ``--use-sim-policy-wrapper``) takes ``{"observation": flat batched keys (B,1,…), "options"}`` and returns
``[action, info]`` with ``action.*`` (B, 16, D); it also has ``reset`` and ``get_modality_config``.

Gripper: GR00T's LIBERO checkpoints output [0, 1] with 1 = open (the RLDS convention), so upstream inverts:
N1.5 ``examples/Libero/eval/utils.py:normalize_gripper_action`` computes ``sign(1 - 2x)``, N1.6+
``gr00t/eval/sim/LIBERO/libero_env.py`` ``normalize_gripper_action`` (``sign(2x - 1)``) then
``invert_gripper_action`` (x -1). Both are our ``gripper=01inv`` (the default): 0.9 -> -1 (open).

RoboCasa365 (``?keys=robocasa365``, the default): RoboCasa's own gym wrapper keys (``robocasa/wrappers/gym_wrapper.py``:
``video.robot0_agentview_left/_right``, ``video.robot0_eye_in_hand`` at 256 px, ``state.<segment>``,
``annotation.human.task_description``; ``action.<segment>`` unmapped by RoboCasa, gripper and control mode
thresholded at 0.5: no gripper map). N1.5 speaks as RoboCasa365's fork (robocasa-benchmark/Isaac-GR00T
``scripts/run_eval.py``, ``gr00t/eval/simulation.py``) does: its vector env's flat batched keys (B, 1, …) in one
``get_action``, framed by ``torch.save`` (``TorchSerializer``; ``?serializer=msgpack`` for a later N1.5 server).
``?keys=squarefk``: Isaac-GR00T N1.6's ``examples/robocasa`` set-up on squarefk/robocasa's ``GrootRoboCasaEnv``
(``video.res256_image_side_0/_side_1/_wrist_0`` from 512 px renders).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from indgen_vla.core.errors import ConfigError, IndgenError, PolicyConnectionError, PolicyError
from indgen_vla.core.protocol.interface import (
    TABLETOP,
    EnvSpec,
    Observation,
    PolicySpec,
    validate_chunk,
)
from policy_wrappers.image_tools import GRIPPER_MODES
from policy_wrappers.layouts import GROOT_ROBOCASA_KEYS, Layout, checked, layout_for, spans
from policy_wrappers.msgpack_numpy import groot_packb, groot_unpackb
from policy_wrappers.remote import REMOTE_OPTIONS, RemoteConfig, RemotePolicy
from policy_wrappers.torch_wire import looks_like_torch, torch_packb, torch_unpackb
from policy_wrappers.transforms import (
    LIBERO_GROOT_N15,
    LIBERO_GROOT_N16,
    ROBOCASA365_GROOT_N15,
    ROBOCASA365_GROOT_N16,
    ROBOCASA_GROOT_N16,
    Conventions,
)

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


@dataclass(frozen=True, kw_only=True)
class GrootConfig(RemoteConfig):
    """Endpoint, API version and the modality map from our Observation (defaults: GR00T's LIBERO example)."""

    api: str = "n1.6"
    api_token: str | None = None
    video: tuple[tuple[str, str], ...] = (("image", "agentview"), ("wrist_image", "wrist"))
    state: tuple[tuple[str, int, int], ...] = LIBERO_STATE
    action: tuple[str, ...] = LIBERO_ACTION
    language_key: str = "annotation.human.action.task_description"
    keys: str = "robocasa365"  # on RoboCasa365: whose modality keys (layouts.GROOT_ROBOCASA_KEYS)
    serializer: str | None = None  # msgpack or torch (None: the server's of this API and keys)
    env_spec: EnvSpec | None = None  # the scene family's contract (None: the tabletop one)
    layout: Layout | None = field(init=False, default=None)  # GR00T's keys on that family (layouts.py)

    def __post_init__(self) -> None:
        if self.api not in APIS:
            raise ConfigError(f"groot {self.url}: api must be n1.5 or n1.6, got {self.api!r}")
        if self.keys not in GROOT_ROBOCASA_KEYS:
            raise ConfigError(
                f"groot {self.url}: keys must be one of {sorted(GROOT_ROBOCASA_KEYS)}, got {self.keys!r}"
            )
        if self.serializer not in (None, *SERIALIZERS):
            raise ConfigError(
                f"groot {self.url}: serializer must be msgpack or torch, got {self.serializer!r}"
            )
        layout = layout_for("groot", self.env_spec)
        if layout is not None:
            layout = checked(GROOT_ROBOCASA_KEYS[self.keys], self.env_spec)
        object.__setattr__(self, "layout", layout)
        if self.keys == "squarefk" and layout is not None and self.api != "n1.6":
            raise ConfigError(
                f"groot {self.url}: keys=squarefk is Isaac-GR00T N1.6's RoboCasa set-up (examples/robocasa); "
                "use api=n1.6, or keys=robocasa365 for RoboCasa365's N1.5 checkpoints"
            )
        cams = (self.env_spec or TABLETOP).cameras
        bad = [cam for _, cam in self.video if cam not in cams]
        if bad or not self.video:
            raise ConfigError(
                f"groot {self.url}: video map needs cameras from {list(cams)}, got {bad or 'none'}"
            )
        dim = (self.env_spec or TABLETOP).state_dim
        if sum(hi - lo for _, lo, hi in self.state) > dim or any(
            not 0 <= lo < hi <= dim for _, lo, hi in self.state
        ):
            raise ConfigError(f"groot {self.url}: state slices must lie within our {dim}-d state")
        super().__post_init__()

    def family_conventions(self) -> Conventions:
        if self.layout is None:
            return APIS[self.api].upstream
        if self.keys == "squarefk":
            return ROBOCASA_GROOT_N16
        return ROBOCASA365_GROOT_N15 if self.api == "n1.5" else ROBOCASA365_GROOT_N16

    @property
    def wire(self) -> str:
        """The serializer: the option, else torch for RoboCasa365's N1.5 fork server, else msgpack."""
        if self.serializer is not None:
            return self.serializer
        return (
            "torch"
            if self.layout is not None and self.keys == "robocasa365" and self.api == "n1.5"
            else "msgpack"
        )


class GrootPolicy(RemotePolicy):
    """ZMQ REQ client for one GR00T inference server: socket, handshake, modality check, action parsing.
    The two API versions (``GrootN15Policy``, ``GrootN16Policy``) differ only in their messages."""

    family, schemes, default_port, server = "groot", ("tcp",), 5555, "the GR00T server"
    batched: ClassVar[bool]
    upstream: ClassVar[Conventions]  # the API version's LIBERO eval; config.conventions applies the options
    action_hint: ClassVar[str] = ""  # added to a get_action error: the other API's spec option

    def __init__(self, name: str, config: GrootConfig):
        import zmq

        self._zmq = zmq
        env = config.env_spec
        self.layout = config.layout  # recorded in the run's fingerprint
        self._action_dim = (env or TABLETOP).action_dim
        # the keys' concatenation order -> ours (identity on the tabletop families)
        self._to_scene = config.layout.action_to_scene(env) if config.layout is not None else None
        scene_cams = (env or TABLETOP).cameras
        cams = tuple(c for c in scene_cams if c in {cam for _, cam in config.video})
        chunk, replan = config.chunking()
        spec = PolicySpec(
            self.family,
            name,
            chunk_size=chunk,
            replan_steps=replan,
            cameras=cams,
            image_size=(config.conventions.render,) * 2,
            batched=self.batched,
            flip_180=config.conventions.flips,
            action_dim=self._action_dim,
        )
        super().__init__(spec, config)
        # The process-wide context: a per-policy one, when the garbage collector frees a policy caught in a
        # reference cycle (an exception's traceback), can be finalised before its socket and block forever.
        self._ctx = zmq.Context.instance()
        self._sock = None
        self._pack, self._unpack = SERIALIZERS[config.wire]
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

    def _map_error(self, error: BaseException, connecting: bool) -> IndgenError | None:
        if isinstance(error, self._zmq.ZMQError):
            return PolicyConnectionError(
                f"policy {self.spec.name}: ZMQ error talking to {self.config.url}: {error}"
            )
        return None

    def call(self, endpoint: str, data=None, requires_input: bool = True, timeout_s: float | None = None):
        """One request/reply. A timeout or ZMQ error raises PolicyConnectionError and rebuilds the REQ socket
        (so the next call reconnects); an error reply from the server raises PolicyError."""
        request: dict = {"endpoint": endpoint}
        if requires_input:
            request["data"] = data
        if self.config.api_token:
            request["api_token"] = self.config.api_token
        timeout = self.config.timeout_s if timeout_s is None else timeout_s
        with self.transport(f" to {endpoint!r}", timeout_s=timeout):
            sock = self._socket()
            sock.send(self._pack(request))
            if not sock.poll(int(timeout * 1000)):
                raise TimeoutError
            message = sock.recv()
        if message == b"ERROR":
            raise self.fail("server error (is it the right GR00T policy server?)")
        try:
            response = self._unpack(message)
        except Exception as e:
            raise self.fail(self._undecodable(message, e)) from None
        if isinstance(response, dict) and "error" in response:
            first = (str(response["error"]).strip().splitlines() or [""])[0][:300]
            hint = self.action_hint if endpoint == "get_action" else ""
            raise self.fail(f"server error: {first}{hint}")
        return response

    def _undecodable(self, message: bytes, error: Exception) -> str:
        """Why a reply could not be read, naming the serializer option when the server speaks the other one."""
        first = (str(error).strip().splitlines() or [""])[0][:200]
        if self.config.wire == "msgpack" and looks_like_torch(message):
            return (
                "the server answers in torch.save archives (RoboCasa365's GR00T N1.5 fork, TorchSerializer); "
                "add ?serializer=torch"
            )
        if self.config.wire == "torch" and not looks_like_torch(message):
            return "the server answers in msgpack (Isaac-GR00T's later service); add ?serializer=msgpack"
        return f"undecodable reply ({type(error).__name__}: {first})"

    def ping(self) -> None:
        """GR00T's ``ping`` endpoint."""
        self.call("ping", requires_input=False, timeout_s=self.config.connect_timeout_s)

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
                other = [
                    name
                    for name, layout in GROOT_ROBOCASA_KEYS.items()
                    if self.layout is not None and set(theirs) <= {k for k, _ in layout.cameras}
                ]
                fix = f"add ?keys={other[0]}" if other else f"set ?{modality}=... to map {missing}"
                raise self.fail(f"server expects {modality} keys {theirs}; our map gives {ours} ({fix})")
        lang = (
            (self.modality_config.get("language") or {})
            if isinstance(self.modality_config.get("language"), dict)
            else {}
        )
        if lang.get("modality_keys") and self._language_key not in lang["modality_keys"]:
            self._language_key = str(lang["modality_keys"][0])

    def _images(self, obs: Observation, cam: str) -> np.ndarray:
        if cam not in obs.images:
            raise self.fail(f"needs camera {cam!r}; observation has {sorted(obs.images)}")
        return np.ascontiguousarray(self.config.conventions.images(obs.images[cam]))

    def batch_keys(self, observations: Sequence[Observation]) -> tuple[dict, dict]:
        """Flat GR00T keys, batched with a time axis: ({video.K: (B, 1, H, W, 3)}, {state.K: (B, 1, D)})."""
        video = {
            f"video.{key}": np.stack([self._images(o, cam) for o in observations])[:, None]
            for key, cam in self.config.video
        }
        state = {
            f"state.{key}": np.stack([o.state[lo:hi] for o in observations])[:, None]
            for key, lo, hi in self.config.state
        }
        return video, state

    def make_observation(self, observations: Sequence[Observation]) -> dict:
        """The ``get_action`` observation in this API's shapes."""
        raise NotImplementedError

    def _parse_actions(self, action: dict, batch: int) -> np.ndarray:
        if not isinstance(action, dict):
            raise self.fail(f"action reply is {type(action).__name__}, not a dict")
        parts = []
        for key in self.config.action:
            name = f"action.{key}"
            value = action.get(name, action.get(key))
            if value is None:
                raise self.fail(f"reply lacks {name!r} (got {sorted(action)})")
            arr = np.asarray(value, dtype=np.float32)
            if arr.ndim == 1:
                arr = arr[:, None]
            if arr.ndim == 2:
                arr = arr[None]
            if arr.ndim != 3 or arr.shape[0] != batch:
                raise self.fail(f"{name} has shape {np.shape(value)}; expected (T, D) or (B, T, D)")
            parts.append(arr)
        if len({p.shape[1] for p in parts}) != 1:
            raise self.fail(f"action keys disagree on the horizon: {[p.shape for p in parts]}")
        chunk = np.concatenate(parts, axis=-1)
        if chunk.shape[-1] != self._action_dim or chunk.shape[1] < self.spec.replan_steps:
            raise PolicyError(
                f"policy {self.spec.name} returned actions of shape {chunk.shape}; expected "
                f"({batch}, >={self.spec.replan_steps}, {self._action_dim})"
            )
        return chunk[:, : self.spec.chunk_size]

    def predict(self, observations: Sequence[Observation]) -> np.ndarray:
        """The raw (B, T, 7) chunk the server returns for ``observations``."""
        raise NotImplementedError

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        chunk = validate_chunk(
            self.predict(observations), len(observations), self.spec.name, self._action_dim
        )
        chunk = self.config.conventions.actions(chunk)
        return chunk if self._to_scene is None else np.ascontiguousarray(self._to_scene(chunk))


class GrootN15Policy(GrootPolicy):
    """N1.5 (``gr00t/eval/service.py``): one unbatched observation per ``get_action``, no ``reset``."""

    batched, upstream = False, LIBERO_GROOT_N15

    def make_observation(self, observations: Sequence[Observation]) -> dict:
        """Flat keys of the first observation, time axis leading: video (1, H, W, 3), state (1, D) float64."""
        video, state = self.batch_keys(observations)
        out = {k: v[0] for k, v in video.items()}
        out.update({k: v[0].astype(np.float64) for k, v in state.items()})
        out[self._language_key] = [o.instruction for o in observations]
        return out

    def predict(self, observations: Sequence[Observation]) -> np.ndarray:
        chunks = []
        for obs in observations:
            reply = self.call("get_action", self.make_observation([obs]))
            if isinstance(reply, list | tuple):
                raise self.fail("got [action, info]; this is an N1.6 server (use ?api=n1.6)")
            chunks.append(self._parse_actions(reply, 1)[0])
        return np.stack(chunks)


class GrootN15VectorPolicy(GrootN15Policy):
    """N1.5 as RoboCasa365's fork evaluates (``gr00t/eval/simulation.py`` over a gym vector env of
    ``MultiStepWrapper`` wrappers): the whole batch in one flat ``get_action``, video (B, 1, H, W, 3) uint8, state
    (B, 1, D) float32 (its gym wrapper's cast), the language a tuple of B strings; ``action.*`` (B, T, D) back."""

    batched = True

    def make_observation(self, observations: Sequence[Observation]) -> dict:
        video, state = self.batch_keys(observations)
        out = dict(video)
        out.update({k: v.astype(np.float32) for k, v in state.items()})
        out[self._language_key] = tuple(o.instruction for o in observations)
        return out

    def predict(self, observations: Sequence[Observation]) -> np.ndarray:
        reply = self.call("get_action", self.make_observation(observations))
        if isinstance(reply, list | tuple):
            raise self.fail("got [action, info]; this is an N1.6 server (use ?api=n1.6)")
        return self._parse_actions(reply, len(observations))


class GrootN16Policy(GrootPolicy):
    """N1.6+ (``gr00t/policy/server_client.py``, ``--use-sim-policy-wrapper``): the whole batch in one
    ``get_action`` ``{"observation", "options"}`` returning ``[action, info]``; ``reset`` per episode."""

    batched, upstream = True, LIBERO_GROOT_N16
    action_hint = " (if this is an N1.5 server, add ?api=n1.5)"

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self.call("reset", {"options": None})

    def make_observation(self, observations: Sequence[Observation]) -> dict:
        """Flat batched keys: video (B, 1, H, W, 3), state (B, 1, D) float32, language [B strings]."""
        video, state = self.batch_keys(observations)
        out = dict(video)
        out.update({k: v.astype(np.float32) for k, v in state.items()})
        out[self._language_key] = [o.instruction for o in observations]
        return out

    def predict(self, observations: Sequence[Observation]) -> np.ndarray:
        reply = self.call("get_action", {"observation": self.make_observation(observations), "options": None})
        if not isinstance(reply, list | tuple) or len(reply) != 2:
            raise self.fail(
                f"N1.6 get_action must return [action, info], got {type(reply).__name__}; is this an N1.5 "
                "server? (use ?api=n1.5)"
            )
        return self._parse_actions(reply[0], len(observations))


APIS: dict[str, type[GrootPolicy]] = {"n1.5": GrootN15Policy, "n1.6": GrootN16Policy}
SERIALIZERS = {"msgpack": (groot_packb, groot_unpackb), "torch": (torch_packb, torch_unpackb)}
# RoboCasa365's gym wrapper (robocasa/wrappers/gym_wrapper.py get_observation) names the instruction so
ROBOCASA365_LANGUAGE = "annotation.human.task_description"


def _pairs(text: str | None) -> tuple[tuple[str, str], ...] | None:
    if not text:
        return None
    out = []
    for item in text.split(","):
        key, sep, cam = item.partition(":")
        if not sep:
            raise ConfigError(
                f"bad groot video mapping {item!r}; write video=image:agentview,wrist_image:wrist"
            )
        out.append((key.strip(), cam.strip()))
    return tuple(out)


OPTIONS = {
    "api_token": "api_token",
    "language_key": "lang_key",
    **REMOTE_OPTIONS,
}  # GrootConfig field -> option


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", env_spec: EnvSpec | None = None
) -> GrootPolicy:
    """``groot:tcp://HOST:PORT[?api=n1.5|n1.6&api_token=&video=key:cam,..&replan=&chunk=&size=&flip=&gripper=
    &keys=robocasa365|squarefk&serializer=msgpack|torch]``.

    On a scene family with its own robot (``env_spec``; RoboCasa365) the keys default to GR00T's there."""
    chosen = {
        "api": options.choice("api", tuple(APIS)),
        "gripper": options.choice("gripper", GRIPPER_MODES),
        "video": _pairs(options.str("video")),
        "keys": options.choice("keys", tuple(GROOT_ROBOCASA_KEYS)),
        "serializer": options.choice("serializer", tuple(SERIALIZERS)),
    }
    values = {k: v for k, v in chosen.items() if v is not None} | options.fields(GrootConfig, OPTIONS)
    if layout_for("groot", env_spec) is not None:
        # GR00T's RoboCasa keys: cameras, one state key per segment, action keys in order
        layout = GROOT_ROBOCASA_KEYS[values.get("keys", "robocasa365")]
        ours = spans(env_spec.state_parts)
        values.setdefault("video", layout.cameras)
        values["state"] = tuple((name, *ours[name]) for name, _ in layout.state)
        values["action"] = tuple(name for name, _ in layout.action)
        if layout is GROOT_ROBOCASA_KEYS["robocasa365"]:
            values.setdefault("language_key", ROBOCASA365_LANGUAGE)
    config = GrootConfig(url=GrootPolicy.url_from(parsed), env_spec=env_spec, **values)
    vector = config.layout is GROOT_ROBOCASA_KEYS["robocasa365"] and config.api == "n1.5"
    return (GrootN15VectorPolicy if vector else APIS[config.api])(parsed.spec, config)
