"""The GR00T client against loopback ZMQ REP servers shaped like Isaac-GR00T's N1.5 and N1.6 services."""

from __future__ import annotations

import io
import re
import threading

import msgpack
import numpy as np
import pytest

from indgen_vla.core.errors import PolicyError
from policy_wrappers.image_tools import flip_180
from policy_wrappers.specs import load_policy

zmq = pytest.importorskip("zmq")
pytestmark = pytest.mark.timeout(60)
KEYS = ("x", "y", "z", "roll", "pitch", "yaw", "gripper")


def decode(obj):  # gr00t MsgSerializer.decode_custom_classes, written out independently
    if isinstance(obj, dict) and "__ndarray_class__" in obj:
        return np.load(io.BytesIO(obj["as_npy"]), allow_pickle=False)
    return obj


def encode(obj):  # gr00t MsgSerializer.encode_custom_classes
    if isinstance(obj, np.ndarray):
        buf = io.BytesIO()
        np.save(buf, obj, allow_pickle=False)
        return {"__ndarray_class__": True, "as_npy": buf.getvalue()}
    return obj


def torch_to_bytes(obj) -> bytes:  # RoboCasa365's N1.5 fork gr00t/eval/service.py TorchSerializer.to_bytes
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    return buf.getvalue()


def torch_from_bytes(data: bytes):  # TorchSerializer.from_bytes, as upstream's server reads requests
    import torch

    return torch.load(io.BytesIO(data), weights_only=False)


WIRES = {
    "msgpack": (lambda o: msgpack.packb(o, default=encode), lambda b: msgpack.unpackb(b, object_hook=decode)),
    "torch": (torch_to_bytes, torch_from_bytes),
}


class GrootServer:
    """A REP socket loop like gr00t's PolicyServer: ping, kill, get_modality_config, reset, get_action.

    ``wire="torch"``: RoboCasa365's GR00T N1.5 fork (robocasa-benchmark/Isaac-GR00T, read from its copy
    XingxinHE/Isaac-GR00T 9d7d7a9eb7ad30bd8ce30448d9ab53a918b45b10, gr00t/eval/service.py BaseInferenceServer.run):
    torch.save framing, and any failure, an undecodable request included, answered as {"error": str(e)}."""

    def __init__(self, get_action, modality=None, token=None, silent=False, wire="msgpack"):
        self.get_action, self.modality, self.token, self.silent = get_action, modality or {}, token, silent
        self.pack, self.unpack = WIRES[wire]
        self.requests = []
        self.ctx = zmq.Context()
        self.sock = self.ctx.socket(zmq.REP)
        self.port = self.sock.bind_to_random_port("tcp://127.0.0.1")
        self.running = True

    def _loop(self):
        while self.running:
            if not self.sock.poll(50):
                continue
            try:
                request = self.unpack(self.sock.recv())
            except Exception as e:  # both services answer a request they cannot read with its error
                self.sock.send(self.pack({"error": str(e)}))
                continue
            self.requests.append(request)
            if self.silent:
                self.running = False
                break
            if self.token and request.get("api_token") != self.token:
                result = {"error": "Unauthorized: Invalid API token"}
            else:
                endpoint = request.get("endpoint", "get_action")
                try:
                    result = {
                        "ping": lambda d: {"status": "ok", "message": "Server is running"},
                        "get_modality_config": lambda d: self.modality,
                        "reset": lambda d: {},
                        "get_action": self.get_action,
                    }[endpoint](request.get("data"))
                except Exception as e:  # gr00t replies {"error": str(e)}
                    result = {"error": str(e)}
            self.sock.send(self.pack(result))

    def __enter__(self):
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.running = False
        self.thread.join(2)
        self.sock.close(linger=0)
        self.ctx.term()


def upstream_n15_gripper(x):
    """Isaac-GR00T N1.5 ``examples/Libero/eval/utils.py:normalize_gripper_action(binarize=True)``, written out."""
    return np.sign(1 - 2 * (np.asarray(x, np.float64) - 0.0) / (1.0 - 0.0))


def upstream_n16_gripper(x):
    """Isaac-GR00T N1.6+ ``gr00t/eval/sim/LIBERO/libero_env.py``: ``normalize_gripper_action`` (2x - 1, sign)
    then ``invert_gripper_action`` (x -1), as ``LiberoEnv.step`` applies them, written out."""
    return np.sign(2 * (np.asarray(x, np.float64) - 0.0) / (1.0 - 0.0) - 1) * -1.0


N15_GRIPPER = 0.9  # the model says "open" (GR00T's LIBERO data: 1 = open); LIBERO must get -1


def n15_reply(data):
    if "observation" in data:  # what a real N1.5 Gr00tPolicy does with an N1.6-shaped request
        raise KeyError("video.image")
    assert data["video.image"].dtype == np.uint8 and data["video.image"].shape == (1, 256, 256, 3)
    assert data["video.wrist_image"].shape == (1, 256, 256, 3)
    for key in KEYS[:-1]:
        assert data[f"state.{key}"].shape == (1, 1) and data[f"state.{key}"].dtype == np.float64
    assert data["state.gripper"].shape == (1, 2)
    assert isinstance(data["annotation.human.action.task_description"], list)
    return {
        f"action.{k}": np.full(
            (16, 1) if k != "x" else (16,), N15_GRIPPER if k == "gripper" else 0.1, np.float32
        )
        for k in KEYS
    }


def test_n15_flat_keys(obs_factory):
    with GrootServer(n15_reply) as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5")
        assert not policy.spec.batched and (policy.spec.chunk_size, policy.spec.replan_steps) == (16, 1)
        obs = obs_factory(1)
        chunk = policy.act([obs, obs_factory(2)])
        policy.close()
    assert chunk.shape == (2, 16, 7) and np.allclose(chunk[..., :6], 0.1)
    assert upstream_n15_gripper(N15_GRIPPER) == -1.0  # open, in LIBERO's (and our) -1 open / +1 close
    assert np.all(chunk[..., 6] == upstream_n15_gripper(N15_GRIPPER))
    data = srv.requests[-2]["data"]  # first get_action (after ping and get_modality_config)
    assert srv.requests[0] == {"endpoint": "ping"} and srv.requests[1] == {"endpoint": "get_modality_config"}
    assert np.array_equal(data["video.image"][0], flip_180(obs.images["agentview"]))
    assert np.allclose(np.concatenate([data[f"state.{k}"][0] for k in KEYS]), obs.state)
    assert data["annotation.human.action.task_description"] == [obs.instruction]


def test_n16_batched_with_reset_and_modality_config(obs_factory):
    modality = {
        "video": {
            "__ModalityConfig_class__": True,
            "as_json": {"delta_indices": [0], "modality_keys": ["image", "wrist_image"]},
        },
        "language": {
            "__ModalityConfig_class__": True,
            "as_json": {"delta_indices": [0], "modality_keys": ["annotation.human.task_description"]},
        },
    }

    def reply(data):
        obs = data["observation"]
        assert set(data) == {"observation", "options"} and data["options"] is None
        assert obs["video.image"].shape == (3, 1, 256, 256, 3) and obs["state.gripper"].shape == (3, 1, 2)
        assert obs["state.x"].dtype == np.float32 and obs["annotation.human.task_description"] == [
            "a",
            "b",
            "c",
        ]
        return [
            {f"action.{k}": np.full((3, 16, 2 if k == "gripper" else 1), 0.2, np.float32) for k in KEYS},
            {},
        ]

    def gripper_two(data):  # a wrong action dimension must be refused
        return [{f"action.{k}": np.zeros((1, 16, 2), np.float32) for k in KEYS}, {}]

    with GrootServer(reply, modality=_raw(modality), token="t") as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api_token=t")
        assert policy.spec.batched and policy.spec.replan_steps == 8
        policy.reset("a", seed=0)
        with pytest.raises(PolicyError, match=re.escape("shape (3, 16, 8)")):
            policy.act([obs_factory(i, instruction=s) for i, s in enumerate("abc")])
        assert srv.requests[2] == {"endpoint": "reset", "data": {"options": None}, "api_token": "t"}
    with GrootServer(gripper_two) as srv:
        with pytest.raises(PolicyError, match="expected"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}").act([obs_factory()])


def _raw(modality):
    """The server sends ModalityConfig as the custom class marker (decoded by our client into dicts)."""
    return {k: dict(v) for k, v in modality.items()}


def test_n16_good_reply(obs_factory):
    def reply(data):
        n = len(data["observation"]["annotation.human.action.task_description"])
        return [{f"action.{k}": np.full((n, 16, 1), 0.3, np.float32) for k in KEYS}, {}]

    with GrootServer(reply) as srv:
        chunk = load_policy(f"groot:tcp://127.0.0.1:{srv.port}?gripper=raw").act(
            [obs_factory(0), obs_factory(1)]
        )
    assert chunk.shape == (2, 16, 7) and np.allclose(chunk, 0.3)


def test_errors(obs_factory):
    with GrootServer(lambda d: (_ for _ in ()).throw(ValueError("bad video key"))) as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}")
        with pytest.raises(PolicyError, match="server error: bad video key"):
            policy.act([obs_factory()])
    with GrootServer(n15_reply, token="t") as srv:
        with pytest.raises(PolicyError, match="Unauthorized"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5")
    with GrootServer(n15_reply) as srv:  # an N1.5 server asked the N1.6 way
        with pytest.raises(PolicyError, match=r"api=n1.5"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}").act([obs_factory()])
    modality = {"video": {"delta_indices": [0], "modality_keys": ["video.ego_view"]}}
    with GrootServer(n15_reply, modality=modality) as srv:
        with pytest.raises(PolicyError, match="ego_view"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5")
    with GrootServer(n15_reply, silent=True) as srv:
        with pytest.raises(PolicyError, match="no reply .* within 0.3s"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}?connect_timeout=0.3")


@pytest.mark.parametrize("model_gripper", [0.0, 0.1, 0.49, 0.51, 0.9, 1.0])
def test_n16_gripper_follows_upstream_libero_env(obs_factory, model_gripper):
    """The default gripper map equals N1.6's LiberoEnv.step: 0.9 (open) -> -1, 0.1 (closed) -> +1."""

    def reply(data):
        n = len(data["observation"]["annotation.human.action.task_description"])
        acts = {f"action.{k}": np.full((n, 16, 1), 0.05, np.float32) for k in KEYS}
        acts["action.gripper"][:] = model_gripper
        return [acts, {}]

    with GrootServer(reply) as srv:
        chunk = load_policy(f"groot:tcp://127.0.0.1:{srv.port}").act([obs_factory(0)])
    expected = upstream_n16_gripper(np.float32(model_gripper))
    assert expected == upstream_n15_gripper(np.float32(model_gripper))  # N1.5 and N1.6 agree
    assert np.all(chunk[..., 6] == expected) and np.allclose(chunk[..., :6], 0.05)
