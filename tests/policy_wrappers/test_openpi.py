"""The openpi client against a loopback server that speaks openpi's websocket protocol and checks requests."""

from __future__ import annotations

import asyncio
import re

import numpy as np
import pytest
from loopback import WebsocketServer

from indgen_vla.core.errors import PolicyError
from policy_wrappers import msgpack_numpy
from policy_wrappers.image_tools import resize_with_pad
from policy_wrappers.specs import load_policy

pytestmark = pytest.mark.timeout(60)


def openpi_server(reply, seen: list, headers: list | None = None):
    """A server shaped like openpi's WebsocketPolicyServer: metadata frame, then request -> reply."""

    async def handler(ws):
        if headers is not None:
            headers.append(ws.request.headers.get("Authorization"))
        await ws.send(msgpack_numpy.packb({"action_horizon": 10}))
        async for message in ws:
            assert isinstance(message, bytes)
            obs = msgpack_numpy.unpackb(message)
            seen.append(obs)
            out = reply(obs)
            if out == "hang":
                await asyncio.sleep(1)
                continue
            if isinstance(out, str):  # openpi sends the traceback as text, then closes with 1011
                await ws.send(out)
                await ws.close(code=1011, reason="Internal server error")
                return
            await ws.send(msgpack_numpy.packb(out))

    return WebsocketServer(handler)


def test_request_matches_openpi_libero_example(obs_factory):
    seen, headers = [], []
    actions = np.linspace(-1, 1, 70, dtype=np.float32).reshape(10, 7)
    with openpi_server(
        lambda obs: {"actions": actions, "server_timing": {"infer_ms": 1.0}}, seen, headers
    ) as srv:
        policy = load_policy(f"openpi:ws://127.0.0.1:{srv.port}?api_key=secret")
        assert policy.metadata == {"action_horizon": 10}
        assert (policy.spec.chunk_size, policy.spec.replan_steps, policy.spec.flip_180) == (10, 5, True)
        obs = obs_factory(3)
        policy.reset(obs.instruction, seed=1)
        chunk = policy.act([obs, obs_factory(4)])
        policy.close()
    assert headers[0] == "Api-Key secret"
    assert chunk.shape == (2, 10, 7) and chunk.dtype == np.float32 and np.allclose(chunk[0], actions)
    req = seen[0]
    assert set(req) == {"observation/image", "observation/wrist_image", "observation/state", "prompt"}
    for key, cam in (("observation/image", "agentview"), ("observation/wrist_image", "wrist")):
        assert req[key].dtype == np.uint8 and req[key].shape == (224, 224, 3)
        assert np.array_equal(req[key], openpi_resize_with_pad(obs.images[cam][::-1, ::-1], 224, 224))
    assert req["observation/image"][-10:].mean() > 250  # the bright top band is now at the bottom
    assert req["observation/state"].shape == (8,) and np.allclose(req["observation/state"], obs.state)
    assert req["prompt"] == obs.instruction


def openpi_resize_with_pad(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """openpi ``packages/openpi-client/src/openpi_client/image_tools.py:_resize_with_pad_pil``, written out:
    ratio = max(w / W, h / H), PIL bilinear to (int(w / ratio), int(h / ratio)), pasted at the integer centre."""
    from PIL import Image

    h, w = img.shape[:2]
    if (h, w) == (height, width):
        return img
    ratio = max(w / width, h / height)
    rh, rw = int(h / ratio), int(w / ratio)
    resized = np.asarray(Image.fromarray(img).resize((rw, rh), resample=Image.BILINEAR))
    out = np.zeros((height, width, 3), np.uint8)
    top, left = max(0, int((height - rh) / 2)), max(0, int((width - rw) / 2))
    out[top : top + rh, left : left + rw] = resized
    return out


def test_resize_with_pad_matches_openpi_semantics():
    img = np.full((100, 200, 3), 200, np.uint8)
    out = resize_with_pad(img, 224, 224)
    assert out.shape == (224, 224, 3)
    assert out[:55].max() == 0 and out[-55:].max() == 0 and out[112, 112, 0] == 200  # letterboxed with zeros
    rng = np.random.default_rng(0)
    for shape in ((256, 256, 3), (100, 200, 3), (181, 97, 3)):  # LIBERO's 256 render, and letterboxed ones
        img = rng.integers(0, 256, shape, dtype=np.uint8)
        assert np.array_equal(resize_with_pad(img, 224, 224), openpi_resize_with_pad(img, 224, 224))


def test_server_error_frame_then_reconnect(obs_factory):
    seen = []
    calls = iter(
        ["Traceback (most recent call last):\nValueError: bad prompt", {"actions": np.zeros((10, 7))}]
    )
    with openpi_server(lambda obs: next(calls), seen) as srv:
        policy = load_policy(f"openpi:ws://127.0.0.1:{srv.port}")
        with pytest.raises(PolicyError, match="server error: ValueError: bad prompt") as err:
            policy.act([obs_factory()])
        assert srv.port and str(srv.port) in str(err.value)
        assert policy.act([obs_factory()]).shape == (1, 10, 7)  # the engine's retry reconnects


@pytest.mark.parametrize(
    "reply, fragment",
    [
        ({"actions": np.zeros((10, 8))}, "shape (10, 8)"),
        ({"actions": np.zeros((3, 7))}, "returned 3 actions"),
        ({"actions": np.full((10, 7), np.nan)}, "non-finite"),
        ({"nope": 1}, "no 'actions'"),
    ],
)
def test_bad_replies_become_policy_errors(obs_factory, reply, fragment):
    with openpi_server(lambda obs: reply, []) as srv:
        policy = load_policy(f"openpi:ws://127.0.0.1:{srv.port}")
        with pytest.raises(PolicyError, match=re.escape(fragment)) as err:
            policy.act([obs_factory()])
        assert f"openpi:ws://127.0.0.1:{srv.port}" in str(err.value)


def test_timeout_and_refused(obs_factory):
    with openpi_server(lambda obs: "hang", []) as srv:
        policy = load_policy(f"openpi:ws://127.0.0.1:{srv.port}?timeout=0.3")
        with pytest.raises(PolicyError, match="no reply .* within 0.3s"):
            policy.act([obs_factory()])
        port = srv.port
    with pytest.raises(PolicyError, match="connection refused"):
        load_policy(f"openpi:ws://127.0.0.1:{port}")


def test_a_host_that_does_not_resolve_names_the_fix(monkeypatch):
    """A typo in the host: the name lookup's failure (socket.gaierror, raised here without a DNS query) says to
    check the host name, not only that the server cannot be reached."""
    import socket

    import websockets.sync.client as client

    def no_such_host(*args, **kwargs):
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(client, "connect", no_such_host)
    with pytest.raises(
        PolicyError, match="cannot resolve the host of ws://gpu-boxx:8000 .*check the host name"
    ):
        load_policy("openpi:ws://gpu-boxx:8000")  # the client connects to read the server's metadata
