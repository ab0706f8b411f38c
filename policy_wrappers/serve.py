"""``indgen serve``: any policy spec behind openpi's websocket protocol (+ ``/healthz``), so openpi clients work.

Requests use the keys of openpi's LIBERO example: images arrive rotated 180° (the client's training-time
convention), so the server rotates them back to the simulator's raw orientation before the wrapped policy
applies its own conventions. Replies are ``{"actions": (T, 7) float32, "server_timing": {...}}``.
One policy instance serves all connections, one request at a time; a new prompt (or our client's
``indgen/reset`` hint) calls ``reset``, so stateful (non-batched) policies should serve one simulator each, or
be served with ``session`` (a fresh policy per connection, e.g. per-episode history over one shared model).
"""

from __future__ import annotations

import asyncio
import http
import logging
import threading
import time
import traceback

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import QUERY_KEY, Observation
from policy_wrappers import msgpack_numpy
from policy_wrappers.image_tools import flip_180
from policy_wrappers.openpi import HISTORY_PREFIX, INDGEN_SERVER, LIBERO_KEYS, QUERY_WIRE
from policy_wrappers.specs import load_policy

log = logging.getLogger(__name__)


def observation_from_request(request: dict, unflip: bool = True) -> Observation:
    """openpi LIBERO request dict -> our ``Observation`` (images back to raw orientation; the earlier steps'
    images, ``HISTORY_PREFIX`` keys, as ``Observation.history`` when the client sent them)."""
    if not isinstance(request, dict):
        raise ValueError(f"request must be a dict, got {type(request).__name__}")
    missing = [k for k in ("observation/image", "observation/state") if k not in request]
    if missing:
        raise KeyError(
            f"request lacks {missing}; send openpi's LIBERO keys observation/image, "
            "observation/wrist_image, observation/state, prompt"
        )
    images, history = {}, {}
    for key, cam in LIBERO_KEYS:
        if key in request:
            images[cam] = _image(request[key], unflip)
        if HISTORY_PREFIX + key in request:
            history[cam] = [_image(img, unflip) for img in np.asarray(request[HISTORY_PREFIX + key])]
    lengths = {len(frames) for frames in history.values()}
    if len(lengths) > 1:
        raise ValueError(
            f"history stacks of different lengths {sorted(lengths)}; send one frame per step and camera"
        )
    steps = lengths.pop() if lengths else 0
    state = np.asarray(request["observation/state"], dtype=np.float32).reshape(-1)
    extras = {}
    if QUERY_WIRE in request:  # the query's identity: a sampling policy draws this query's own noise from it
        key = np.asarray(request[QUERY_WIRE]).reshape(-1)
        if key.size != 2 or key.dtype.kind not in "iu":
            raise ValueError(
                f"{QUERY_WIRE} must be two integers (episode seed, steps taken), got {key.tolist()}"
            )
        extras[QUERY_KEY] = (int(key[0]), int(key[1]))
    return Observation(
        images=images, state=state, instruction=str(request.get("prompt", "")), extras=extras,
        history=tuple({cam: frames[k] for cam, frames in history.items()} for k in range(steps)),
    )  # fmt: skip


def _image(value, unflip: bool) -> np.ndarray:
    """One request image as uint8 HxWx3 (floats in [0, 1] scaled, CHW transposed), rotated back if ``unflip``."""
    img = np.asarray(value)
    if img.dtype != np.uint8:
        img = (255 * img).astype(np.uint8) if np.issubdtype(img.dtype, np.floating) else img.astype(np.uint8)
    if img.ndim == 3 and img.shape[0] == 3 and img.shape[-1] != 3:
        img = np.transpose(img, (1, 2, 0))
    return flip_180(img) if unflip else np.ascontiguousarray(img)


class PolicyServer:
    """Serves one ``Policy`` over openpi's websocket protocol; acting runs in a worker thread under a lock."""

    def __init__(
        self,
        policy,
        host: str = "127.0.0.1",
        port: int = 8000,
        api_key: str | None = None,
        unflip: bool = True,
        session=None,
    ):
        self.policy, self.host, self.port, self.api_key, self.unflip = policy, host, port, api_key, unflip
        self.session = session  # () -> Policy for each connection; None: ``policy`` serves them all
        spec = policy.spec
        self.metadata = {
            "server": INDGEN_SERVER,
            "policy": spec.name,
            "family": spec.family,
            "chunk_size": spec.chunk_size,
            "replan_steps": spec.replan_steps,
            "cameras": list(spec.cameras),
            "flip_180": spec.flip_180,
            "image_size": list(spec.image_size) if spec.image_size else None,
            "reads_observations": spec.reads_observations,
        }
        self._lock: asyncio.Lock | None = None
        self._server = None
        self.bound_port: int | None = None
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None

    def _process_request(self, connection, request):
        if request.path == "/healthz":
            return connection.respond(http.HTTPStatus.OK, "OK\n")
        if self.api_key and request.headers.get("Authorization") != f"Api-Key {self.api_key}":
            return connection.respond(
                http.HTTPStatus.UNAUTHORIZED, "missing or wrong 'Authorization: Api-Key ...'\n"
            )
        return None

    def _act(self, request: dict, state: dict) -> np.ndarray:
        obs = observation_from_request(request, self.unflip)
        policy = state.get("policy", self.policy)
        hint = request.get("indgen/reset")
        if isinstance(hint, dict):
            seed = int(hint.get("seed", -1))
            policy.reset(str(hint.get("instruction", obs.instruction)), None if seed < 0 else seed)
            state["prompt"] = obs.instruction
        elif state.get("prompt") != obs.instruction:
            policy.reset(obs.instruction, None)
            state["prompt"] = obs.instruction
        return np.asarray(policy.act([obs])[0], dtype=np.float32)

    async def _handler(self, websocket) -> None:
        import websockets

        await websocket.send(msgpack_numpy.packb(self.metadata))
        state: dict = {} if self.session is None else {"policy": self.session()}
        prev_total = None
        while True:
            try:
                start = time.monotonic()
                request = msgpack_numpy.unpackb(await websocket.recv())
                infer_start = time.monotonic()
                async with self._lock:
                    actions = await asyncio.to_thread(self._act, request, state)
                timing = {"infer_ms": (time.monotonic() - infer_start) * 1000}
                if prev_total is not None:
                    timing["prev_total_ms"] = prev_total * 1000
                await websocket.send(msgpack_numpy.packb({"actions": actions, "server_timing": timing}))
                prev_total = time.monotonic() - start
            except websockets.ConnectionClosed:
                break
            except Exception:
                log.exception("request failed")
                try:
                    await websocket.send(traceback.format_exc())
                    await websocket.close(
                        code=1011, reason="Internal server error. Traceback included in previous frame."
                    )
                except websockets.ConnectionClosed:
                    pass
                break

    async def run(self, on_listening=None) -> None:
        """Serve until stopped; ``on_listening(port)`` runs once the socket is bound (not before: a busy port fails)."""
        from websockets.asyncio.server import serve

        self._lock = asyncio.Lock()
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(
            self._handler,
            self.host,
            self.port,
            compression=None,
            max_size=None,
            process_request=self._process_request,
        ) as server:
            self.bound_port = server.sockets[0].getsockname()[1] if server.sockets else self.port
            self._ready.set()
            if on_listening is not None:
                on_listening(int(self.bound_port))
            await self._stop.wait()

    def start_background(self, timeout_s: float = 10.0) -> int:
        """Run in a daemon thread (tests, benchmark); return the bound port (pass port=0 for an ephemeral one)."""
        thread = threading.Thread(target=lambda: asyncio.run(self.run()), daemon=True, name="indgen-serve")
        thread.start()
        if not self._ready.wait(timeout_s):
            raise RuntimeError("policy server did not start")
        self._thread = thread
        return int(self.bound_port)

    def stop(self) -> None:
        """Stop a server started with ``start_background``."""
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
            getattr(self, "_thread", None) and self._thread.join(timeout=5)


def serve(
    policy: str, *, host: str = "127.0.0.1", port: int = 8000, api_key: str | None = None,
    trust_remote_code: bool = False, on_listening=None,
) -> None:  # fmt: skip
    """``indgen serve``: load the policy spec and serve it until Ctrl-C; ``on_listening(spec_name, port)`` hears
    when the port is bound."""
    if not 0 <= int(port) <= 65535:
        raise ConfigError(f"--port must be in 0..65535, got {port}")
    loaded = load_policy(policy, trust_remote_code=bool(trust_remote_code))
    server = PolicyServer(loaded, host=host, port=int(port), api_key=api_key)
    if host not in ("127.0.0.1", "localhost", "::1") and not server.api_key:
        log.warning(
            "serving on %s without --api-key: anyone who can reach this port can drive the policy", host
        )

    def listening(bound: int) -> None:
        if on_listening is not None:
            on_listening(loaded.spec.name, bound)

    try:
        asyncio.run(server.run(on_listening=listening))
    except KeyboardInterrupt:
        pass
    except OSError as e:
        raise ConfigError(f"cannot listen on {host}:{port}: {e.strerror or e}") from None
    finally:
        loaded.close()
