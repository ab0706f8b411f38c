"""The OpenVLA(-OFT) client against a loopback ``POST /act`` server speaking json-numpy."""

from __future__ import annotations

import base64
import json
import re
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest
from numpy.lib.format import descr_to_dtype, dtype_to_descr

from indgen_vla.core.errors import ConfigError, PolicyError
from policy_wrappers.image_tools import center_crop_tf, flip_180, resize_jpeg_lanczos
from policy_wrappers.specs import load_policy

pytestmark = pytest.mark.timeout(60)


def jn_hook(d):  # json_numpy.object_hook, written out independently of the client's codec
    if "__numpy__" in d:
        arr = np.frombuffer(base64.b64decode(d["__numpy__"]), descr_to_dtype(d["dtype"]))
        return arr.reshape(d["shape"]) if d["shape"] else arr[0]
    return d


def jn_default(o):  # json_numpy.default
    return {
        "__numpy__": base64.b64encode(np.ascontiguousarray(o).tobytes()).decode(),
        "dtype": dtype_to_descr(o.dtype),
        "shape": o.shape,
    }


class DeployServer:
    """Shaped like vla-scripts/deploy.py: POST /act, JSONResponse(action) or the JSON string "error"."""

    def __init__(self, reply):
        self.reply, self.seen, self.raw = reply, [], []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802
                assert self.path == "/act" and self.headers["Content-Type"] == "application/json"
                body = self.rfile.read(int(self.headers["Content-Length"]))
                outer.raw.append(json.loads(body))
                payload = json.loads(body, object_hook=jn_hook)
                outer.seen.append(payload)
                out = outer.reply(payload)
                if isinstance(out, str) and out == "hang":
                    time.sleep(1.0)
                    out = "error"
                data = json.dumps(out, default=jn_default).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = self.httpd.server_address[1]

    def __enter__(self):
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()
        return self

    def __exit__(self, *exc):
        self.httpd.shutdown()
        self.httpd.server_close()


def test_oft_payload_and_chunk(obs_factory):
    actions = [np.array([0.1, 0, 0, 0, 0, 0.2, g], np.float32) for g in (0.9, 0.1) * 4]
    with DeployServer(lambda p: actions) as srv:
        policy = load_policy(f"openvla-oft:http://127.0.0.1:{srv.port}")
        assert (policy.spec.chunk_size, policy.spec.replan_steps, policy.spec.image_size) == (
            8,
            8,
            (256, 256),
        )
        obs = obs_factory(2)
        chunk = policy.act([obs])
    assert chunk.shape == (1, 8, 7) and chunk.dtype == np.float32
    assert np.allclose(chunk[0, :, :6], np.stack(actions)[:, :6])
    assert list(chunk[0, :2, 6]) == [-1.0, 1.0]  # OpenVLA: 0.9 -> +1 -> flipped to -1 (open)
    raw, req = srv.raw[0], srv.seen[0]
    assert set(raw) == {"full_image", "wrist_image", "state", "instruction"}
    assert raw["full_image"]["dtype"] == "|u1" and raw["full_image"]["shape"] == [224, 224, 3]
    assert raw["state"]["dtype"] == "<f4" and raw["state"]["shape"] == [8]
    assert np.array_equal(req["full_image"], resize_jpeg_lanczos(flip_180(obs.images["agentview"]), 224, 224))
    assert np.allclose(req["state"], obs.state) and req["instruction"] == obs.instruction


def test_base_openvla_variant(obs_factory):
    with DeployServer(lambda p: np.array([0, 0, 0.01, 0, 0, 0, 0.0], np.float64)) as srv:
        policy = load_policy(
            f"openvla-oft:http://127.0.0.1:{srv.port}?variant=openvla&unnorm_key=libero_spatial"
        )
        chunk = policy.act([obs_factory(), obs_factory(1)])
    assert chunk.shape == (2, 1, 7) and chunk[0, 0, 2] == pytest.approx(0.01) and chunk[0, 0, 6] == 1.0
    assert (
        set(srv.seen[0]) == {"image", "instruction", "unnorm_key"}
        and srv.seen[0]["unnorm_key"] == "libero_spatial"
    )
    assert policy.spec.cameras == ("agentview",) and policy.spec.replan_steps == 1


def tf_center_crop_reference(img: np.ndarray, crop_scale: float = 0.9) -> np.ndarray:
    """openvla ``experiments/robot/openvla_utils.py:get_vla_action(center_crop=True)`` pixel by pixel:
    ``convert_image_dtype`` (u8 * 1/255), ``crop_and_resize`` with the box ``(1 - sqrt(s)) / 2 ..
    (1 + sqrt(s)) / 2`` and TF's bilinear kernel (``crop_and_resize_op.cc``: ``in_y = y1 * (H - 1) + y *
    (y2 - y1) * (H - 1) / (crop_h - 1)``, floor/ceil neighbours, lerp x then y), then the saturating cast
    back (``x * 255.5`` truncated)."""
    f32 = np.float32
    h, w, _ = img.shape
    side = f32(np.sqrt(f32(crop_scale)))
    y1 = x1 = (f32(1) - side) / f32(2)
    y2 = x2 = y1 + side
    src = img.astype(f32) * f32(1 / 255)
    out = np.zeros(img.shape, np.uint8)
    hs = (y2 - y1) * f32(h - 1) / f32(h - 1)
    ws = (x2 - x1) * f32(w - 1) / f32(w - 1)
    for y in range(h):
        in_y = y1 * f32(h - 1) + f32(y) * hs
        t, b = int(np.floor(in_y)), int(np.ceil(in_y))
        yl = in_y - f32(t)
        for x in range(w):
            in_x = x1 * f32(w - 1) + f32(x) * ws
            left, r = int(np.floor(in_x)), int(np.ceil(in_x))
            xl = in_x - f32(left)
            top = src[t, left] + (src[t, r] - src[t, left]) * xl
            bottom = src[b, left] + (src[b, r] - src[b, left]) * xl
            val = np.clip(top + (bottom - top) * yl, 0, 1) * f32(255.5)
            out[y, x] = np.minimum(val, 255).astype(np.uint8)
    return out


def test_center_crop_matches_tf_formula():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    got = center_crop_tf(img, 0.9)
    assert got.shape == img.shape and got.dtype == np.uint8
    assert np.array_equal(got, tf_center_crop_reference(img, 0.9))
    # 0.9 of the area, not of the side: the first output row samples row (1 - sqrt(0.9)) / 2 * 63 = 0.8277
    ramp = np.repeat(np.arange(64, dtype=np.uint8)[:, None, None] * 4, 64, axis=1).repeat(3, axis=2)
    first = center_crop_tf(ramp, 0.9)[0, 0, 0]
    assert first == int(np.float32((1 - np.sqrt(0.9)) / 2 * 63 * 4 / 255 * 255.5))
    assert np.array_equal(center_crop_tf(img, 1.0), img)  # the whole box is the identity


def test_base_openvla_crops_and_picks_unnorm_key(obs_factory):
    with DeployServer(lambda p: np.array([0, 0, 0.01, 0, 0, 0, 0.9], np.float64)) as srv:
        url = f"openvla-oft:http://127.0.0.1:{srv.port}?variant=openvla"
        obs = obs_factory(4)
        chunk = load_policy(url, scene="libero_object").act([obs])
        load_policy(url + "&center_crop=0", scene="pick_place").act([obs])
        load_policy(url + "&unnorm_key=bridge_orig", scene="libero_object").act([obs])
    resized = resize_jpeg_lanczos(flip_180(obs.images["agentview"]), 224, 224)
    cropped, plain, explicit = srv.seen
    assert np.array_equal(cropped["image"], center_crop_tf(resized))  # checked against TF's formula above
    assert (
        cropped["unnorm_key"] == "libero_object_no_noops"
    )  # run_libero_eval: <suite>, else <suite>_no_noops
    assert np.array_equal(plain["image"], resized) and "unnorm_key" not in plain
    assert explicit["unnorm_key"] == "bridge_orig"
    assert chunk[0, 0, 6] == -np.sign(2 * 0.9 - 1)  # normalize_gripper_action then invert_gripper_action


def test_base_openvla_error_without_unnorm_key(obs_factory):
    with DeployServer(lambda p: "error") as srv:
        policy = load_policy(f"openvla-oft:http://127.0.0.1:{srv.port}?variant=openvla", scene="pick_place")
        with pytest.raises(PolicyError, match=r"several datasets needs \?unnorm_key=KEY"):
            policy.act([obs_factory()])


def test_openvla_defaults_and_refusals(obs_factory):
    # each deploy.py's own default port: base OpenVLA 8000, OFT 8777 (probed at load)
    import socket

    for variant, port in (("openvla", 8000), ("oft", 8777)):
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                pytest.skip(f"something listens on 127.0.0.1:{port}")
        with pytest.raises(PolicyError, match=f"127.0.0.1:{port}"):
            load_policy(f"openvla-oft:http://127.0.0.1?variant={variant}&connect_timeout=0.5")
    with pytest.raises(ConfigError, match="center-crops server-side"):
        load_policy("openvla-oft:http://127.0.0.1:9?center_crop=1")
    with pytest.raises(ConfigError, match="--unnorm_key"):
        load_policy("openvla-oft:http://127.0.0.1:9?unnorm_key=libero_spatial")


def test_double_encoded_fallback(obs_factory):
    def reply(payload):
        assert set(payload) == {"encoded"}
        inner = json.loads(payload["encoded"], object_hook=jn_hook)
        assert inner["full_image"].shape == (224, 224, 3)
        return json.dumps([np.zeros(7, np.float32)] * 8, default=jn_default)

    with DeployServer(reply) as srv:
        assert load_policy(f"openvla-oft:http://127.0.0.1:{srv.port}?encoded=1").act(
            [obs_factory()]
        ).shape == (1, 8, 7)


@pytest.mark.parametrize(
    "reply, fragment",
    [
        ("error", "server replied 'error'"),
        ([np.zeros(6, np.float32)] * 8, "shape (8, 6)"),
        ([np.zeros(7, np.float32)] * 3, "shape (3, 7)"),
        ([np.full(7, np.nan, np.float32)] * 8, "non-finite"),
    ],
)
def test_bad_replies(obs_factory, reply, fragment):
    with DeployServer(lambda p: reply) as srv:
        policy = load_policy(f"openvla-oft:http://127.0.0.1:{srv.port}")
        with pytest.raises(PolicyError, match=re.escape(fragment)) as err:
            policy.act([obs_factory()])
    assert f"openvla-oft:http://127.0.0.1:{srv.port}" in str(err.value)


def test_timeout_and_refused(obs_factory):
    with DeployServer(lambda p: "hang") as srv:
        with pytest.raises(PolicyError, match="no reply"):
            load_policy(f"openvla-oft:http://127.0.0.1:{srv.port}?timeout=0.2").act([obs_factory()])
        port = srv.port
    time.sleep(0.1)
    with pytest.raises(PolicyError, match="connection refused"):
        load_policy(f"openvla-oft:http://127.0.0.1:{port}")  # probed at load, like the other remotes
