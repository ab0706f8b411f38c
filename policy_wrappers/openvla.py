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

from indgen_vla.core.errors import ConfigError, IndgenError, PolicyConnectionError, PolicyError
from indgen_vla.core.protocol.interface import ACTION_DIM, Observation, PolicySpec, validate_chunk
from policy_wrappers.image_tools import GRIPPER_MODES
from policy_wrappers.remote import REMOTE_OPTIONS, RemoteConfig, RemotePolicy
from policy_wrappers.transforms import LIBERO_OFT, LIBERO_OPENVLA, CenterCrop, Conventions

LIBERO_SUITES = ("libero_spatial", "libero_object", "libero_goal", "libero_10", "libero_90")
PORTS = {"oft": 8777, "openvla": 8000}  # DeployConfig.port of each repository's vla-scripts/deploy.py
CONVENTIONS = {"oft": LIBERO_OFT, "openvla": LIBERO_OPENVLA}


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


@dataclass(frozen=True, kw_only=True)
class OpenVLAConfig(RemoteConfig):
    """Endpoint, variant (oft | openvla) and overrides of the variant's conventions (``CONVENTIONS``)."""

    variant: str = "oft"
    unnorm_key: str | None = None
    center_crop: bool | None = None  # None: the variant's (base OpenVLA crops client-side, as its eval)
    encoded: bool = False  # deploy.py's double-encoded fallback {"encoded": "<json>"}

    def __post_init__(self) -> None:
        if self.variant not in CONVENTIONS:
            raise ConfigError(f"openvla-oft {self.url}: variant must be oft or openvla, got {self.variant!r}")
        super().__post_init__()
        if self.variant == "openvla" and self.chunking()[0] != 1:
            raise ConfigError(f"openvla-oft {self.url}: base OpenVLA returns one action; chunk must be 1")
        if self.variant == "oft" and self.conventions.images.find(CenterCrop):
            raise ConfigError(
                f"openvla-oft {self.url}: OFT's deploy.py center-crops server-side (its --center_crop); "
                "drop ?center_crop=1 so the image is not cropped twice"
            )
        if self.variant == "oft" and self.unnorm_key:
            raise ConfigError(
                f"openvla-oft {self.url}: OFT's deploy.py takes the un-normalisation key on its own command "
                "line (--unnorm_key), not per request; drop ?unnorm_key="
            )

    def family_conventions(self) -> Conventions:
        return CONVENTIONS[self.variant]

    def more_overrides(self) -> dict:
        return {"crop": self.center_crop}


class OpenVLAPolicy(RemotePolicy):
    """HTTP client for one OpenVLA(-OFT) deploy server; one request per observation."""

    family, schemes, default_port, server = "openvla-oft", ("http", "https"), PORTS["oft"], "deploy.py"

    def __init__(self, name: str, config: OpenVLAConfig):
        cams = ("agentview", "wrist") if config.variant == "oft" else ("agentview",)
        chunk, replan = config.chunking()
        spec = PolicySpec(
            self.family,
            name,
            chunk_size=chunk,
            replan_steps=replan,
            cameras=cams,
            image_size=(config.conventions.render,) * 2,
            flip_180=config.conventions.flips,
        )
        super().__init__(spec, config)
        self._probe()

    def ping(self) -> None:
        """A TCP connect (deploy.py has no ping route)."""
        self._probe()

    def _probe(self) -> None:
        """Fail at load time, with one clear line, when nothing listens at the URL (deploy.py has no ping)."""
        import socket
        from urllib.parse import urlsplit

        parts = urlsplit(self.config.url)
        with self.transport(connecting=True):
            socket.create_connection(
                (parts.hostname, parts.port), timeout=self.config.connect_timeout_s
            ).close()

    def _map_error(self, error: BaseException, connecting: bool) -> IndgenError | None:
        import http.client

        if isinstance(error, urllib.error.HTTPError):
            kind = (
                PolicyConnectionError if error.code >= 500 else PolicyError
            )  # 5xx: proxy or restarting server
            return kind(
                f"policy {self.spec.name}: server answered HTTP {error.code} {error.reason} on POST /act"
            )
        if isinstance(error, urllib.error.URLError) and not isinstance(error.reason, OSError):
            return self.fail(f"cannot reach {self.config.url}: {error.reason}")
        if isinstance(error, http.client.HTTPException):  # closed mid-reply (IncompleteRead)
            return PolicyConnectionError(
                f"policy {self.spec.name}: connection to {self.config.url} failed: {type(error).__name__}: {error}"
            )
        return None

    def _image(self, obs: Observation, cam: str) -> np.ndarray:
        if cam not in obs.images:
            raise self.fail(f"needs camera {cam!r}; observation has {sorted(obs.images)}")
        return self.config.conventions.images(obs.images[cam])

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
        body = dumps({"encoded": dumps(payload)} if self.config.encoded else payload).encode()
        req = urllib.request.Request(
            self.config.url + "/act", data=body, method="POST", headers={"Content-Type": "application/json"}
        )
        name = self.spec.name
        with self.transport():
            try:
                with urllib.request.urlopen(req, timeout=self.config.timeout_s) as resp:
                    raw = resp.read()
            except urllib.error.HTTPError:
                raise
            except urllib.error.URLError as e:  # the socket's own fault inside: refused, timed out, reset
                if isinstance(e.reason, OSError):
                    raise e.reason from None
                raise
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
        return self.config.conventions.actions(chunk)


def default_unnorm_key(variant: str, scene: str | None) -> str | None:
    """Base OpenVLA on a LIBERO suite: ``<suite>_no_noops``, the key of every released LIBERO fine-tune."""
    return f"{scene}_no_noops" if variant == "openvla" and scene in LIBERO_SUITES else None


OPTIONS = {
    "center_crop": "center_crop",
    "encoded": "encoded",
    **REMOTE_OPTIONS,
}  # OpenVLAConfig field -> option


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", scene: str | None = None
) -> OpenVLAPolicy:
    """``openvla-oft:http://HOST:PORT[?variant=oft|openvla&unnorm_key=&center_crop=&gripper=&size=&replan=..]``;
    ``scene`` (passed by the engine) picks base OpenVLA's default ``unnorm_key`` on LIBERO suites."""
    variant = options.choice("variant", tuple(CONVENTIONS)) or OpenVLAConfig.variant
    values = options.fields(OpenVLAConfig, OPTIONS)
    gripper = options.choice("gripper", GRIPPER_MODES)
    if gripper is not None:
        values["gripper"] = gripper
    config = OpenVLAConfig(
        url=OpenVLAPolicy.url_from(parsed, PORTS[variant]),
        variant=variant,
        unnorm_key=options.str("unnorm_key", default_unnorm_key(variant, scene)),
        **values,
    )
    return OpenVLAPolicy(parsed.spec, config)
