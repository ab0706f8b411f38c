"""``openpi:ws://HOST:PORT`` — pi0 / pi0.5 behind openpi's websocket policy server.

Wire format (openpi ``websocket_client_policy.py`` / ``serving/websocket_policy_server.py``): on connect the
server sends one msgpack-numpy frame of metadata; each request is a msgpack-numpy dict in the LIBERO example's
keys (``examples/libero/main.py``) and each reply a dict with ``actions`` (T, 7). A text frame is a server
error (a traceback) after which the server closes the connection.

RoboCasa365 (the scene's ``EnvSpec`` picks ``layouts.OPENPI_ROBOCASA``): RoboCasa365's openpi client
(robocasa-benchmark/openpi ``examples/robocasa/main.py``) sends ``observation/image``, ``observation/wrist_image``,
``observation/right_image`` and the 16-d state, and steps RoboCasa's ``convert_action`` of the (T, 12) reply.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from indgen_vla.core.errors import IndgenError, PolicyConnectionError, PolicyError
from indgen_vla.core.protocol.interface import (
    QUERY_KEY,
    TABLETOP,
    EnvSpec,
    Observation,
    PolicySpec,
    validate_chunk,
)
from policy_wrappers import msgpack_numpy
from policy_wrappers.layouts import Layout, layout_for
from policy_wrappers.remote import REMOTE_OPTIONS, RemoteConfig, RemotePolicy
from policy_wrappers.transforms import LIBERO_OPENPI, ROBOCASA_OPENPI, Compose, Conventions

INDGEN_SERVER = "indgen-vla"  # metadata["server"] of our own `indgen serve`, which accepts reset hints
# request key prefix of the earlier steps' images (Observation.history): HISTORY_PREFIX + the camera's own request
# key, a (steps, H, W, 3) stack oldest first; sent only by clients whose spec declares history_steps, and only
# when there is history (none at an episode's first query)
HISTORY_PREFIX = "indgen/history/"
# request key of the query's identity (the engine's QUERY_KEY: episode seed, steps taken) as int64[2], sent to our own
# server only: a flow-matching policy served by `indgen serve` then draws the noise it would draw in process
QUERY_WIRE = "indgen/query"


@dataclass(frozen=True, kw_only=True)
class OpenpiConfig(RemoteConfig):
    """How to talk to one openpi server; unset conventions are ``LIBERO_OPENPI``'s."""

    api_key: str | None = None
    env_spec: EnvSpec | None = None  # the scene family's contract (None: the tabletop one)
    layout: Layout | None = field(init=False, default=None)  # openpi's keys and order there (layouts.py)

    def __post_init__(self) -> None:
        object.__setattr__(self, "layout", layout_for("openpi", self.env_spec))
        super().__post_init__()

    def family_conventions(self) -> Conventions:
        return ROBOCASA_OPENPI if self.layout is not None else LIBERO_OPENPI


LIBERO_KEYS = (("observation/image", "agentview"), ("observation/wrist_image", "wrist"))


def make_request(obs: Observation, images: Compose, keys=LIBERO_KEYS, state=None) -> dict:
    """One observation in openpi's request format (``images``: e.g. rotate 180°, resize-with-pad; ``keys``:
    (request key, our camera), LIBERO's by default; ``state``: our state -> the order the server reads), with
    its earlier steps' images under ``HISTORY_PREFIX`` keys when it has any."""
    for _, cam in keys:
        if cam not in obs.images:
            raise PolicyError(f"openpi needs the {cam!r} camera but the observation has {sorted(obs.images)}")
    request = {key: images(obs.images[cam]) for key, cam in keys}
    if obs.history:  # the same conventions as the current images (e.g. flipped 180°)
        if any(cam not in frame for frame in obs.history for _, cam in keys):
            raise PolicyError(f"openpi needs the cameras {[c for _, c in keys]} in every history frame too")
        for key, cam in keys:
            request[HISTORY_PREFIX + key] = np.stack([images(frame[cam]) for frame in obs.history])
    s = np.asarray(obs.state, dtype=np.float32)
    request["observation/state"] = s if state is None else np.ascontiguousarray(state(s))
    request["prompt"] = str(obs.instruction)
    return request


class OpenpiPolicy(RemotePolicy):
    """Client for one openpi websocket server; one request per observation."""

    family, schemes, default_port, server = "openpi", ("ws", "wss"), 8000, "the openpi server"
    history_steps = 0  # earlier steps' images sent with each request (a served family's server reads them)

    def __init__(self, name: str, config: OpenpiConfig):
        conv = config.conventions
        chunk, replan = config.chunking()
        env, self.layout = config.env_spec, config.layout
        self._keys = self.layout.cameras if self.layout is not None else LIBERO_KEYS
        self._state = self.layout.state_to_policy(env) if self.layout is not None else None
        self._to_scene = self.layout.action_to_scene(env) if self.layout is not None else None
        self._action_dim = (env or TABLETOP).action_dim
        spec = PolicySpec(
            self.family,
            name,
            chunk_size=chunk,
            replan_steps=replan,
            cameras=tuple(cam for _, cam in self._keys),
            image_size=(conv.render, conv.render),
            flip_180=conv.flips,
            action_dim=self._action_dim,
            history_steps=self.history_steps,
        )
        super().__init__(spec, config)
        self._ws = None
        self._packer = msgpack_numpy.Packer()
        self.metadata: dict = {}
        self._pending_reset: dict | None = None
        self._connect()
        if self.metadata.get("reads_observations") is False:  # `indgen serve` of a blind stand-in says so
            self.spec = replace(self.spec, reads_observations=False)

    def _map_error(self, error: BaseException, connecting: bool) -> IndgenError | None:
        from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidStatus, InvalidURI

        url = self.config.url
        if isinstance(error, InvalidStatus):
            code = error.response.status_code
            hint = "; pass ?api_key=KEY (or set OPENPI_API_KEY)" if code in (401, 403) else ""
            kind = (
                PolicyConnectionError if code >= 500 else PolicyError
            )  # 5xx: a proxy or a restarting server
            return kind(f"policy {self.spec.name}: {url} refused the websocket: {error}{hint}")
        if isinstance(error, InvalidURI):
            return self.fail(f"bad websocket URL {url}: {error}")
        if isinstance(error, InvalidHandshake):  # e.g. the server died during the handshake
            return PolicyConnectionError(
                f"policy {self.spec.name}: websocket handshake with {url} failed: {error}"
            )
        if isinstance(error, ConnectionClosed):
            return PolicyConnectionError(f"policy {self.spec.name}: connection to {url} lost: {error}")
        return None

    def _connect(self) -> None:
        from websockets.sync.client import connect

        headers = {"Authorization": f"Api-Key {self.config.api_key}"} if self.config.api_key else None
        with self.transport(connecting=True):
            ws = connect(
                self.config.url,
                compression=None,
                max_size=None,
                additional_headers=headers,
                open_timeout=self.config.connect_timeout_s,
            )
        try:
            first = ws.recv(timeout=self.config.connect_timeout_s)
        except Exception as e:
            ws.close()
            raise PolicyConnectionError(
                f"policy {self.spec.name}: server at {self.config.url} sent no metadata frame ({type(e).__name__})"
            ) from None
        if isinstance(first, str):
            ws.close()
            raise self.fail(f"server error on connect: {_last_line(first)}")
        meta = msgpack_numpy.unpackb(first)
        self.metadata = meta if isinstance(meta, dict) else {}
        self._ws = ws

    def _drop(self) -> None:
        if self._ws is not None:
            try:
                self._ws.close()
            except Exception:
                pass
        self._ws = None

    def ping(self) -> None:
        """A fresh connection and its metadata frame (openpi's server has no ping message)."""
        self._drop()
        self._connect()

    def reset(self, instruction: str, seed: int | None = None) -> None:
        """openpi's client reset is a no-op; our own server is told about the new episode on the next request."""
        self._pending_reset = {"instruction": instruction, "seed": -1 if seed is None else int(seed)}

    def infer(self, request: dict) -> dict:
        """One round trip; any failure drops the connection (the next call reconnects). Transport faults
        (timeout, reset, closed mid-reply) raise PolicyConnectionError, a server error frame PolicyError."""
        if self._ws is None:
            self._connect()
        with self.transport():
            self._ws.send(self._packer.pack(request))
            reply = self._ws.recv(timeout=self.config.timeout_s)
        if isinstance(reply, str):
            self._drop()
            raise self.fail(f"server error: {_last_line(reply)}")
        try:
            out = msgpack_numpy.unpackb(reply)
        except Exception as e:
            self._drop()
            raise self.fail(f"undecodable reply ({type(e).__name__}: {e})") from None
        if not isinstance(out, dict) or "actions" not in out:
            keys = sorted(out) if isinstance(out, dict) else type(out).__name__
            raise self.fail(f"reply has no 'actions' (got {keys})")
        return out

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        chunks = []
        for obs in observations:
            request = make_request(obs, self.config.conventions.images, self._keys, self._state)
            if self.metadata.get("server") == INDGEN_SERVER:
                if self._pending_reset is not None:
                    request["indgen/reset"] = self._pending_reset
                if QUERY_KEY in obs.extras:
                    request[QUERY_WIRE] = np.asarray(obs.extras[QUERY_KEY], dtype=np.int64)
            out = self.infer(request)
            self._pending_reset = None
            actions = np.asarray(out["actions"])
            if actions.ndim != 2 or actions.shape[1] != self._action_dim:
                raise PolicyError(
                    f"policy {self.spec.name} returned actions of shape {actions.shape}; expected (T, {self._action_dim})"
                )
            if actions.shape[0] < self.spec.replan_steps:
                raise PolicyError(
                    f"policy {self.spec.name} returned {actions.shape[0]} actions but replans every {self.spec.replan_steps}; "
                    "lower ?replan="
                )
            chunks.append(actions.astype(np.float32))
        length = min(c.shape[0] for c in chunks)
        chunk = validate_chunk(
            np.stack([c[:length] for c in chunks]), len(observations), self.spec.name, self._action_dim
        )
        chunk = self.config.conventions.actions(chunk)
        return chunk if self._to_scene is None else np.ascontiguousarray(self._to_scene(chunk))


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "(empty error frame)"


OPTIONS = {"api_key": "api_key", **REMOTE_OPTIONS}  # OpenpiConfig field -> spec option


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", env_spec: EnvSpec | None = None
) -> OpenpiPolicy:
    """Build an ``OpenpiPolicy`` from ``openpi:ws://HOST:PORT[?api_key=&replan=&chunk=&size=&flip=&timeout=]``
    (``env_spec``: the scene family's contract, which picks openpi's request keys there)."""
    import os

    values = options.fields(OpenpiConfig, OPTIONS)
    values.setdefault("api_key", os.environ.get("OPENPI_API_KEY"))
    config = OpenpiConfig(url=OpenpiPolicy.url_from(parsed), env_spec=env_spec, **values)
    return OpenpiPolicy(parsed.spec, config)
