"""``indgen serve``: any policy behind openpi's websocket protocol, checked with our client and a raw one."""

from __future__ import annotations

import urllib.request
from types import SimpleNamespace

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import Observation
from policy_wrappers import msgpack_numpy
from policy_wrappers.image_tools import flip_180, resize_with_pad
from policy_wrappers.serve import PolicyServer, serve
from policy_wrappers.specs import load_policy

pytestmark = pytest.mark.timeout(120)


class Recorder:
    """A real stand-in (noop) that remembers what it was given, to check the server's conversions."""

    def __init__(self):
        self.inner = load_policy("standin:noop")
        self.spec = self.inner.spec
        self.resets, self.seen = [], []

    def reset(self, instruction, seed=None):
        self.resets.append((instruction, seed))

    def act(self, observations):
        self.seen.extend(observations)
        return self.inner.act(observations)

    def close(self):
        pass


@pytest.fixture
def served():
    rec = Recorder()
    server = PolicyServer(rec, port=0, api_key="k")
    port = server.start_background()
    yield rec, port
    server.stop()


def test_healthz_and_api_key(served):
    _, port = served
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=5) as resp:
        assert resp.status == 200 and resp.read() == b"OK\n"
    with pytest.raises(PolicyError, match="api_key"):
        load_policy(f"openpi:ws://127.0.0.1:{port}")


def test_roundtrip_undoes_the_client_flip(served, obs_factory):
    rec, port = served
    client = load_policy(f"openpi:ws://127.0.0.1:{port}?api_key=k&chunk=8&render=224")
    assert client.metadata["server"] == "indgen-vla" and client.metadata["policy"] == "standin:noop"
    assert client.spec.reads_observations is False  # the served noop's declaration reaches the client's spec
    obs = obs_factory(1, size=224)
    client.reset(obs.instruction, seed=11)
    chunk = client.act([obs])
    client.act([obs])
    assert chunk.shape == (1, 8, 7) and np.all(chunk[..., 6] == -1)
    assert rec.resets == [(obs.instruction, 11)]  # the reset hint, and no spurious reset on the second call
    got = rec.seen[0]
    assert np.array_equal(got.images["agentview"], obs.images["agentview"])  # raw orientation again
    assert np.allclose(got.state, obs.state) and got.instruction == obs.instruction


def test_plain_openpi_client_and_error_frame(served, obs_factory):
    from websockets.sync.client import connect

    rec, port = served
    with connect(f"ws://127.0.0.1:{port}", additional_headers={"Authorization": "Api-Key k"}) as ws:
        assert msgpack_numpy.unpackb(ws.recv())["chunk_size"] == 8
        obs = obs_factory(2, size=224)
        request = {
            "observation/image": obs.images["agentview"],
            "observation/wrist_image": obs.images["wrist"],
            "observation/state": obs.state.astype(np.float64),
            "prompt": "stack the blocks",
        }
        ws.send(msgpack_numpy.packb(request))
        reply = msgpack_numpy.unpackb(ws.recv())
        assert reply["actions"].shape == (8, 7) and reply["actions"].dtype == np.float32
        assert "infer_ms" in reply["server_timing"]
        assert rec.resets == [("stack the blocks", None)]  # a new prompt starts a new episode
        ws.send(msgpack_numpy.packb({"prompt": "no images"}))
        error = ws.recv()
        assert isinstance(error, str) and "observation/image" in error


def test_serving_a_lerobot_checkpoint(tiny_act, obs_factory):
    server = PolicyServer(load_policy(f"lerobot:{tiny_act}"), port=0)
    port = server.start_background()
    try:
        client = load_policy(f"openpi:ws://127.0.0.1:{port}?chunk=10&replan=10")
        local = load_policy(f"lerobot:{tiny_act}")
        obs = obs_factory(5, size=32)
        remote_chunk = client.act([obs])
        # the client flips and pads to 224, the server flips back: the checkpoint sees exactly these images
        seen = {cam: flip_180(resize_with_pad(flip_180(img), 224, 224)) for cam, img in obs.images.items()}
        expected = local.act([Observation(seen, obs.state, obs.instruction)])
        assert remote_chunk.shape == (1, 10, 7) and np.allclose(remote_chunk, expected, atol=1e-5)
    finally:
        server.stop()


def test_serve_rejects_bad_port_and_spec():
    with pytest.raises(ConfigError, match="--port"):
        serve("standin:noop", host="127.0.0.1", port=70000)
    with pytest.raises(ConfigError, match="did you mean"):
        serve("standin:nop", host="127.0.0.1", port=0)


def test_a_busy_port_is_one_error_and_never_announced_as_serving(capsys):
    import socket

    from indgen_vla.app.cli.serve import main as serve_main

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(ConfigError, match=f"cannot listen on 127.0.0.1:{port}"):
            serve_main(
                SimpleNamespace(
                    policy="standin:noop", host="127.0.0.1", port=port, api_key=None, trust_remote_code=False
                )
            )
    assert "serving" not in capsys.readouterr().out


def test_indgen_serve_cli_end_to_end(obs_factory):
    """``indgen serve`` as a real process: healthz answers, an openpi client acts, SIGINT stops it cleanly."""
    import signal
    import socket
    import subprocess
    import sys
    import time

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "indgen_vla.app.cli",
            "serve",
            "--policy",
            "standin:random",
            "--port",
            str(port),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a suite started as a background job ignores SIGINT, and children inherit that: restore the default
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=1) as resp:
                    assert resp.status == 200
                    break
            except OSError:
                assert proc.poll() is None and time.monotonic() < deadline, (
                    proc.stderr.read() if proc.poll() else "timeout"
                )
                time.sleep(0.2)
        client = load_policy(f"openpi:ws://127.0.0.1:{port}?chunk=8")
        assert client.act([obs_factory()]).shape == (1, 8, 7)
        client.close()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert f"serving standin:random on ws://127.0.0.1:{port}" in out


def test_indgen_serve_cli_bad_spec_is_one_line():
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "indgen_vla.app.cli", "serve", "--policy", "lerobot:"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert (
        out.returncode != 0
        and out.stderr.strip().count("\n") == 0
        and "nothing after 'lerobot:'" in out.stderr
    )


def test_history_travels_under_its_own_keys_only_when_present(obs_factory):
    """``make_request`` sends ``Observation.history`` as ``indgen/history/<key>`` stacks, transformed like the
    current images; ``observation_from_request`` reads it back in raw orientation; no history, no keys."""
    import dataclasses

    from policy_wrappers.openpi import HISTORY_PREFIX, make_request
    from policy_wrappers.serve import observation_from_request
    from policy_wrappers.transforms import Flip180, compose

    now, before, earlier = obs_factory(1, size=16), obs_factory(2, size=16), obs_factory(3, size=16)
    plain = make_request(now, compose(Flip180()))
    assert not [k for k in plain if k.startswith("indgen/")]
    assert observation_from_request(plain).history == ()
    with_history = dataclasses.replace(now, history=(earlier.images, before.images))
    request = make_request(with_history, compose(Flip180()))
    stack = request[HISTORY_PREFIX + "observation/wrist_image"]
    assert stack.shape == (2, 16, 16, 3) and np.array_equal(stack[1], flip_180(before.images["wrist"]))
    got = observation_from_request(request)
    assert [set(f) for f in got.history] == [{"agentview", "wrist"}] * 2
    for frame, want in zip(got.history, (earlier, before), strict=True):
        assert all(np.array_equal(frame[c], want.images[c]) for c in frame)
    request[HISTORY_PREFIX + "observation/image"] = request[HISTORY_PREFIX + "observation/image"][:1]
    with pytest.raises(ValueError, match=r"history stacks of different lengths \[1, 2\]"):
        observation_from_request(request)


def test_a_served_flow_policy_draws_each_querys_own_noise(tmp_path, obs_factory):
    """Our client sends the query's identity (the engine's QUERY_KEY) to `indgen serve`, so a served flow-matching
    policy samples what it samples in process: the same query gives the same chunk whatever came before it."""
    pytest.importorskip(
        "num2words", reason="transformers' SmolVLMProcessor needs num2words (lerobot[smolvla])"
    )
    import dataclasses

    from indgen_vla.core.protocol.interface import QUERY_KEY
    from tests.fixtures.tiny_policies import build_tiny_smolvla, build_tiny_vlm_dir

    spec = f"lerobot:{build_tiny_smolvla(tmp_path / 'smolvla', build_tiny_vlm_dir(tmp_path / 'vlm'))}"
    server = PolicyServer(load_policy(spec), port=0)
    port = server.start_background()
    try:
        client = load_policy(f"openpi:ws://127.0.0.1:{port}?chunk=10&replan=5")
        obs = obs_factory(5, size=32)
        remote = [
            client.act([dataclasses.replace(obs, extras={QUERY_KEY: k})]) for k in ((7, 0), (7, 5), (7, 0))
        ]
        assert np.array_equal(remote[0], remote[2]) and not np.allclose(remote[0], remote[1])
        seen = {cam: flip_180(resize_with_pad(flip_180(img), 224, 224)) for cam, img in obs.images.items()}
        local = load_policy(spec).act(
            [Observation(seen, obs.state, obs.instruction, extras={QUERY_KEY: (7, 5)})]
        )
        np.testing.assert_allclose(remote[1], local, atol=1e-5)
    finally:
        server.stop()
