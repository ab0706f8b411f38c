"""``openpi:ws://HOST:PORT`` — pi0 / pi0.5 behind openpi's websocket policy server.

Wire format (openpi ``websocket_client_policy.py`` / ``serving/websocket_policy_server.py``): on connect the
server sends one msgpack-numpy frame of metadata; each request is a msgpack-numpy dict in the LIBERO example's
keys (``examples/libero/main.py``) and each reply a dict with ``actions`` (T, 7). A text frame is a server
error (a traceback) after which the server closes the connection.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from indgen_vla.errors import ConfigError, PolicyConnectionError, PolicyError
from indgen_vla.interface import ACTION_DIM, Observation, PolicySpec, validate_chunk
from policy_wrappers import msgpack_numpy
from policy_wrappers.image_tools import flip_180, resize_with_pad

INDGEN_SERVER = "indgen-vla"  # metadata["server"] of our own `indgen serve`, which accepts reset hints


@dataclass(frozen=True)
class OpenpiConfig:
    """How to talk to one openpi server and which LIBERO conventions to apply client-side."""

    url: str
    api_key: str | None = None
    chunk_size: int = 10  # pi0.5 LIBERO action horizon
    replan_steps: int = 5  # openpi examples/libero/main.py
    image_size: int = 224  # sent to the server (resize-with-pad)
    render_size: int = 256  # LIBERO_ENV_RESOLUTION: what the engine renders before the resize
    flip_180: bool = True
    timeout_s: float = 60.0
    connect_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if min(self.image_size, self.render_size) < 8:
            raise ConfigError(
                f"openpi {self.url}: image sizes must be >= 8, got {self.image_size}/{self.render_size}"
            )
        if self.timeout_s <= 0 or self.connect_timeout_s <= 0:
            raise ConfigError(f"openpi {self.url}: timeouts must be positive")


def make_request(obs: Observation, image_size: int, flip: bool) -> dict:
    """One observation in openpi's LIBERO request format (rotate 180°, resize-with-pad, uint8)."""

    def prep(img: np.ndarray) -> np.ndarray:
        img = flip_180(img) if flip else img
        return resize_with_pad(img, image_size, image_size)

    for cam in ("agentview", "wrist"):
        if cam not in obs.images:
            raise PolicyError(f"openpi needs the {cam!r} camera but the observation has {sorted(obs.images)}")
    return {
        "observation/image": prep(obs.images["agentview"]),
        "observation/wrist_image": prep(obs.images["wrist"]),
        "observation/state": np.asarray(obs.state, dtype=np.float32),
        "prompt": str(obs.instruction),
    }


class OpenpiPolicy:
    """Client for one openpi websocket server; one request per observation."""

    def __init__(self, name: str, config: OpenpiConfig):
        self.config = config
        self.spec = PolicySpec(
            "openpi",
            name,
            chunk_size=config.chunk_size,
            replan_steps=config.replan_steps,
            cameras=("agentview", "wrist"),
            image_size=(config.render_size, config.render_size),
            flip_180=config.flip_180,
        )
        self._ws = None
        self._packer = msgpack_numpy.Packer()
        self.metadata: dict = {}
        self._pending_reset: dict | None = None
        self._connect()

    def _connect(self) -> None:
        from websockets.exceptions import InvalidHandshake, InvalidStatus, InvalidURI
        from websockets.sync.client import connect

        headers = {"Authorization": f"Api-Key {self.config.api_key}"} if self.config.api_key else None
        try:
            ws = connect(
                self.config.url,
                compression=None,
                max_size=None,
                additional_headers=headers,
                open_timeout=self.config.connect_timeout_s,
            )
        except ConnectionRefusedError:
            raise PolicyConnectionError(
                f"policy {self.spec.name}: connection refused at {self.config.url}; is the openpi server running?"
            ) from None
        except (TimeoutError, OSError, EOFError) as e:
            raise PolicyConnectionError(
                f"policy {self.spec.name}: cannot reach {self.config.url}: {e or type(e).__name__}"
            ) from None
        except InvalidStatus as e:
            code = e.response.status_code
            hint = "; pass ?api_key=KEY (or set OPENPI_API_KEY)" if code in (401, 403) else ""
            kind = (
                PolicyConnectionError if code >= 500 else PolicyError
            )  # 5xx: a proxy or a restarting server
            raise kind(
                f"policy {self.spec.name}: {self.config.url} refused the websocket: {e}{hint}"
            ) from None
        except InvalidURI as e:
            raise PolicyError(f"policy {self.spec.name}: bad websocket URL {self.config.url}: {e}") from None
        except InvalidHandshake as e:  # e.g. the server died during the handshake
            raise PolicyConnectionError(
                f"policy {self.spec.name}: websocket handshake with {self.config.url} failed: {e}"
            ) from None
        try:
            first = ws.recv(timeout=self.config.connect_timeout_s)
        except Exception as e:
            ws.close()
            raise PolicyConnectionError(
                f"policy {self.spec.name}: server at {self.config.url} sent no metadata frame ({type(e).__name__})"
            ) from None
        if isinstance(first, str):
            ws.close()
            raise PolicyError(f"policy {self.spec.name}: server error on connect: {_last_line(first)}")
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

    def reset(self, instruction: str, seed: int | None = None) -> None:
        """openpi's client reset is a no-op; our own server is told about the new episode on the next request."""
        self._pending_reset = {"instruction": instruction, "seed": -1 if seed is None else int(seed)}

    def infer(self, request: dict) -> dict:
        """One round trip; any failure drops the connection (the next call reconnects). Transport faults
        (timeout, reset, closed mid-reply) raise PolicyConnectionError, a server error frame PolicyError."""
        from websockets.exceptions import ConnectionClosed

        if self._ws is None:
            self._connect()
        try:
            self._ws.send(self._packer.pack(request))
            reply = self._ws.recv(timeout=self.config.timeout_s)
        except TimeoutError:
            self._drop()
            raise PolicyConnectionError(
                f"policy {self.spec.name}: no reply from {self.config.url} within {self.config.timeout_s:g}s"
            ) from None
        except (ConnectionClosed, OSError, EOFError) as e:
            self._drop()
            raise PolicyConnectionError(
                f"policy {self.spec.name}: connection to {self.config.url} lost: {e}"
            ) from None
        if isinstance(reply, str):
            self._drop()
            raise PolicyError(f"policy {self.spec.name}: server error: {_last_line(reply)}")
        try:
            out = msgpack_numpy.unpackb(reply)
        except Exception as e:
            self._drop()
            raise PolicyError(
                f"policy {self.spec.name}: undecodable reply ({type(e).__name__}: {e})"
            ) from None
        if not isinstance(out, dict) or "actions" not in out:
            keys = sorted(out) if isinstance(out, dict) else type(out).__name__
            raise PolicyError(f"policy {self.spec.name}: reply has no 'actions' (got {keys})")
        return out

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        chunks = []
        for obs in observations:
            request = make_request(obs, self.config.image_size, self.config.flip_180)
            if self._pending_reset is not None and self.metadata.get("server") == INDGEN_SERVER:
                request["indgen/reset"] = self._pending_reset
            out = self.infer(request)
            self._pending_reset = None
            actions = np.asarray(out["actions"])
            if actions.ndim != 2 or actions.shape[1] != ACTION_DIM:
                raise PolicyError(
                    f"policy {self.spec.name} returned actions of shape {actions.shape}; expected (T, {ACTION_DIM})"
                )
            if actions.shape[0] < self.spec.replan_steps:
                raise PolicyError(
                    f"policy {self.spec.name} returned {actions.shape[0]} actions but replans every {self.spec.replan_steps}; "
                    "lower ?replan="
                )
            chunks.append(actions.astype(np.float32))
        length = min(c.shape[0] for c in chunks)
        return validate_chunk(np.stack([c[:length] for c in chunks]), len(observations), self.spec.name)

    def close(self) -> None:
        self._drop()


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "(empty error frame)"


def load(parsed, options, *, trust_remote_code: bool = False, device: str = "cpu") -> OpenpiPolicy:
    """Build an ``OpenpiPolicy`` from ``openpi:ws://HOST:PORT[?api_key=&replan=&chunk=&size=&flip=&timeout=]``."""
    import os

    from policy_wrappers.registry import check_url, join_url

    scheme, host, port = check_url(parsed.spec, parsed.target, ("ws", "wss"), 8000)
    chunk = options.int("chunk", 10)
    config = OpenpiConfig(
        url=join_url(scheme, host, port),
        api_key=options.str("api_key", os.environ.get("OPENPI_API_KEY")),
        chunk_size=chunk,
        replan_steps=options.int("replan", min(5, chunk)),
        image_size=options.int("size", 224),
        render_size=options.int("render", 256),
        flip_180=options.bool("flip", True),
        timeout_s=options.float("timeout", 60.0),
        connect_timeout_s=options.float("connect_timeout", 10.0),
    )
    return OpenpiPolicy(parsed.spec, config)
