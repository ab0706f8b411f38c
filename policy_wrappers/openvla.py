"""``openvla-oft:http://HOST:PORT`` — OpenVLA-OFT's ``vla-scripts/deploy.py`` (and base OpenVLA's) REST server.

OFT: ``POST /act`` with a json-numpy body ``{full_image, wrist_image, state, instruction}`` (images rotated 180°
and resized to 224 as in ``experiments/robot/libero/run_libero_eval.py:prepare_observation``); the reply is a
list of 8 json-numpy actions. Base OpenVLA (``?variant=openvla``): ``{image, instruction, unnorm_key}`` -> one
action. Both reply with the JSON string ``"error"`` when inference fails. Gripper outputs follow OpenVLA's
``process_action``: [0, 1] -> [-1, 1], binarised, then sign-flipped (``?gripper=01inv``, the default).

Base OpenVLA's LIBERO eval (``openvla/openvla`` ``experiments/robot/libero/run_libero_eval.py``) center-crops
in-process (``center_crop=True``, ``openvla_utils.py:crop_and_resize``, 0.9 of the area) and its ``deploy.py``
does not, so this client crops (``?center_crop=0`` turns it off); OFT's ``deploy.py`` crops server-side. The
eval's ``unnorm_key`` is the suite name, or ``<suite>_no_noops`` when the checkpoint has that key (all released
LIBERO fine-tunes do): on a LIBERO scene we send ``<scene>_no_noops`` unless ``?unnorm_key=`` says otherwise.
Default ports follow the servers: base ``deploy.py`` 8000, OFT's 8777.

json-numpy (the ``json_numpy`` package the servers patch into ``json``) encodes an ndarray or numpy scalar as
``{"__numpy__": base64(raw bytes), "dtype": numpy descr, "shape": [...]}``; it is implemented here.
"""

from __future__ import annotations

import base64
import json
import urllib.error
import urllib.request
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from indgen_vla.errors import ConfigError, PolicyConnectionError, PolicyError
from indgen_vla.interface import ACTION_DIM, Observation, PolicySpec, validate_chunk
from policy_wrappers.image_tools import (
    GRIPPER_MODES,
    center_crop_tf,
    convert_gripper,
    flip_180,
    resize_jpeg_lanczos,
)

LIBERO_SUITES = ("libero_spatial", "libero_object", "libero_goal", "libero_10", "libero_90")
PORTS = {"oft": 8777, "openvla": 8000}  # DeployConfig.port of each repository's vla-scripts/deploy.py


def _json_default(obj):
    if isinstance(obj, np.ndarray | np.generic):
        from numpy.lib.format import dtype_to_descr

        arr = np.ascontiguousarray(obj)
        return {
            "__numpy__": base64.b64encode(arr.tobytes()).decode(),
            "dtype": dtype_to_descr(arr.dtype),
            "shape": list(arr.shape),
        }
    raise TypeError(f"Object of type {type(obj).__name__} is not JSON serializable")


def _json_hook(dct: dict):
    if "__numpy__" in dct:
        from numpy.lib.format import descr_to_dtype

        dtype = descr_to_dtype(dct["dtype"] if isinstance(dct["dtype"], str) else tuple(dct["dtype"]))
        arr = np.frombuffer(base64.b64decode(dct["__numpy__"]), dtype)
        return arr.reshape(dct["shape"]) if dct["shape"] else arr[0]
    return dct


def dumps(obj) -> str:
    """``json.dumps`` with json-numpy's array encoding."""
    return json.dumps(obj, default=_json_default)


def loads(text: str | bytes):
    """``json.loads`` decoding json-numpy arrays."""
    return json.loads(text, object_hook=_json_hook)


@dataclass(frozen=True)
class OpenVLAConfig:
    """Endpoint, variant (oft | openvla) and the LIBERO conventions applied client-side."""

    url: str
    variant: str = "oft"
    unnorm_key: str | None = None
    image_size: int = 224
    render_size: int = 256
    flip_180: bool = True
    gripper: str = "01inv"
    chunk_size: int = 8  # OFT LIBERO NUM_ACTIONS_CHUNK
    replan_steps: int = 8  # OFT run_libero_eval num_open_loop_steps
    encoded: bool = False  # deploy.py's double-encoded fallback {"encoded": "<json>"}
    center_crop: bool = False  # base OpenVLA: crop 0.9 of the area client-side, as its LIBERO eval does
    timeout_s: float = 60.0
    connect_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if self.variant not in ("oft", "openvla"):
            raise ConfigError(f"openvla-oft {self.url}: variant must be oft or openvla, got {self.variant!r}")
        if self.gripper not in GRIPPER_MODES:
            raise ConfigError(f"openvla-oft {self.url}: gripper must be one of {GRIPPER_MODES}")
        if self.variant == "openvla" and self.chunk_size != 1:
            raise ConfigError(f"openvla-oft {self.url}: base OpenVLA returns one action; chunk must be 1")
        if self.timeout_s <= 0:
            raise ConfigError(f"openvla-oft {self.url}: timeout must be positive")
        if self.variant == "oft" and self.center_crop:
            raise ConfigError(
                f"openvla-oft {self.url}: OFT's deploy.py center-crops server-side (its --center_crop); "
                "drop ?center_crop=1 so the image is not cropped twice"
            )
        if self.variant == "oft" and self.unnorm_key:
            raise ConfigError(
                f"openvla-oft {self.url}: OFT's deploy.py takes the un-normalisation key on its own command "
                "line (--unnorm_key), not per request; drop ?unnorm_key="
            )


class OpenVLAPolicy:
    """HTTP client for one OpenVLA(-OFT) deploy server; one request per observation."""

    def __init__(self, name: str, config: OpenVLAConfig):
        self.config = config
        cams = ("agentview", "wrist") if config.variant == "oft" else ("agentview",)
        self.spec = PolicySpec(
            "openvla-oft",
            name,
            chunk_size=config.chunk_size,
            replan_steps=config.replan_steps,
            cameras=cams,
            image_size=(config.render_size,) * 2,
            flip_180=config.flip_180,
        )
        self._probe()

    def _probe(self) -> None:
        """Fail at load time, with one clear line, when nothing listens at the URL (deploy.py has no ping)."""
        import socket
        from urllib.parse import urlsplit

        parts = urlsplit(self.config.url)
        try:
            socket.create_connection(
                (parts.hostname, parts.port), timeout=self.config.connect_timeout_s
            ).close()
        except ConnectionRefusedError:
            raise PolicyConnectionError(
                f"policy {self.spec.name}: connection refused at {self.config.url}; is deploy.py running?"
            ) from None
        except OSError as e:
            raise PolicyConnectionError(
                f"policy {self.spec.name}: cannot reach {self.config.url}: {e}"
            ) from None

    def _image(self, obs: Observation, cam: str) -> np.ndarray:
        if cam not in obs.images:
            raise PolicyError(
                f"policy {self.spec.name} needs camera {cam!r}; observation has {sorted(obs.images)}"
            )
        img = flip_180(obs.images[cam]) if self.config.flip_180 else obs.images[cam]
        img = resize_jpeg_lanczos(img, self.config.image_size, self.config.image_size)
        return center_crop_tf(img, 0.9) if self.config.center_crop else img

    def make_payload(self, obs: Observation) -> dict:
        """The request body for one observation, before json-numpy encoding."""
        if self.config.variant == "oft":
            return {
                "full_image": self._image(obs, "agentview"),
                "wrist_image": self._image(obs, "wrist"),
                "state": np.asarray(obs.state, dtype=np.float32),
                "instruction": obs.instruction,
            }
        payload = {"image": self._image(obs, "agentview"), "instruction": obs.instruction}
        if self.config.unnorm_key:
            payload["unnorm_key"] = self.config.unnorm_key
        return payload

    def post(self, payload: dict):
        """POST /act and decode the reply; errors become PolicyError naming the policy, transport faults
        (refused, reset, timeout, truncated reply, HTTP 5xx) PolicyConnectionError. Each call is a fresh
        HTTP connection, so the next call after a fault reconnects."""
        import http.client

        body = dumps({"encoded": dumps(payload)} if self.config.encoded else payload).encode()
        req = urllib.request.Request(
            self.config.url + "/act", data=body, method="POST", headers={"Content-Type": "application/json"}
        )
        name = self.spec.name
        try:
            with urllib.request.urlopen(req, timeout=self.config.timeout_s) as resp:
                raw = resp.read()
        except urllib.error.HTTPError as e:
            kind = PolicyConnectionError if e.code >= 500 else PolicyError  # 5xx: proxy or restarting server
            raise kind(f"policy {name}: server answered HTTP {e.code} {e.reason} on POST /act") from None
        except urllib.error.URLError as e:
            reason = e.reason
            if isinstance(reason, ConnectionRefusedError):
                raise PolicyConnectionError(
                    f"policy {name}: connection refused at {self.config.url}; is deploy.py running?"
                ) from None
            if isinstance(reason, TimeoutError):
                raise PolicyConnectionError(
                    f"policy {name}: no reply from {self.config.url} within {self.config.timeout_s:g}s"
                ) from None
            if isinstance(reason, OSError):
                raise PolicyConnectionError(
                    f"policy {name}: cannot reach {self.config.url}: {reason}"
                ) from None
            raise PolicyError(f"policy {name}: cannot reach {self.config.url}: {reason}") from None
        except TimeoutError:
            raise PolicyConnectionError(
                f"policy {name}: no reply from {self.config.url} within {self.config.timeout_s:g}s"
            ) from None
        except (OSError, http.client.HTTPException) as e:  # reset, or closed mid-reply (IncompleteRead)
            raise PolicyConnectionError(
                f"policy {name}: connection to {self.config.url} failed: {type(e).__name__}: {e}"
            ) from None
        try:
            out = loads(raw)
            if self.config.encoded and isinstance(out, str) and out != "error":
                out = loads(out)
        except (ValueError, TypeError) as e:
            raise PolicyError(f"policy {name}: reply is not json-numpy ({e})") from None
        if isinstance(out, str):
            if self.config.variant == "openvla" and not self.config.unnorm_key:
                raise PolicyError(
                    f"policy {name}: server replied {out!r}; a checkpoint with several datasets needs "
                    "?unnorm_key=KEY (one of the keys of its norm_stats, e.g. libero_spatial_no_noops)"
                )
            hint = (
                f"is unnorm_key {self.config.unnorm_key!r} one of the checkpoint's norm_stats keys? set ?unnorm_key="
                if self.config.variant == "openvla"
                else "bad request, or the server's --unnorm_key?"
            )
            raise PolicyError(f"policy {name}: server replied {out!r}; its log has the traceback ({hint})")
        return out

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        chunks = []
        for obs in observations:
            out = self.post(self.make_payload(obs))
            try:
                actions = np.asarray(out, dtype=np.float32)
            except (ValueError, TypeError):
                raise PolicyError(
                    f"policy {self.spec.name}: reply is not an action array ({type(out).__name__})"
                ) from None
            if self.config.variant == "openvla" and actions.ndim == 1:
                actions = actions[None]
            if (
                actions.ndim != 2
                or actions.shape[1] != ACTION_DIM
                or actions.shape[0] < self.spec.replan_steps
            ):
                raise PolicyError(
                    f"policy {self.spec.name} returned actions of shape {actions.shape}; expected "
                    f"(>={self.spec.replan_steps}, {ACTION_DIM})"
                )
            chunks.append(actions[: self.spec.chunk_size])
        chunk = validate_chunk(np.stack(chunks), len(observations), self.spec.name)
        return convert_gripper(chunk, self.config.gripper)

    def reset(self, instruction: str, seed: int | None = None) -> None:
        pass

    def close(self) -> None:
        pass


def default_unnorm_key(variant: str, scene: str | None) -> str | None:
    """Base OpenVLA on a LIBERO suite: ``<suite>_no_noops``, the key of every released LIBERO fine-tune."""
    return f"{scene}_no_noops" if variant == "openvla" and scene in LIBERO_SUITES else None


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", scene: str | None = None
) -> OpenVLAPolicy:
    """``openvla-oft:http://HOST:PORT[?variant=oft|openvla&unnorm_key=&center_crop=&gripper=&size=&replan=..]``;
    ``scene`` (passed by the engine) picks base OpenVLA's default ``unnorm_key`` on LIBERO suites."""
    from policy_wrappers.registry import check_url, join_url

    variant = options.choice("variant", ("oft", "openvla"), "oft")
    scheme, host, port = check_url(parsed.spec, parsed.target, ("http", "https"), PORTS[variant])
    chunk = options.int("chunk", 8 if variant == "oft" else 1)
    config = OpenVLAConfig(
        url=join_url(scheme, host, port),
        variant=variant,
        unnorm_key=options.str("unnorm_key", default_unnorm_key(variant, scene)),
        center_crop=bool(options.bool("center_crop", variant == "openvla")),
        image_size=options.int("size", 224),
        render_size=options.int("render", 256),
        flip_180=options.bool("flip", True),
        gripper=options.choice("gripper", GRIPPER_MODES, "01inv"),
        chunk_size=chunk,
        replan_steps=options.int("replan", chunk),
        encoded=bool(options.bool("encoded", False)),
        timeout_s=options.float("timeout", 60.0),
        connect_timeout_s=options.float("connect_timeout", 10.0),
    )
    return OpenVLAPolicy(parsed.spec, config)
