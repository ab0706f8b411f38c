"""Policy spec strings (``family:target[?options]``) -> loaded ``Policy``; ``indgen policies`` listing.

Importing this module is cheap: each family's module (and torch/lerobot) loads only when its spec is used.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl

from indgen_vla.core.errors import ConfigError, PolicyError, UnknownNameError
from indgen_vla.core.registry import Registry
from indgen_vla.core.runs.redact import redact

if TYPE_CHECKING:
    from indgen_vla.core.protocol.interface import EnvSpec, ScenePreview

FAMILIES: Registry = Registry("policy family")
FAMILIES.register(
    "lerobot",
    "policy_wrappers.lerobot_policy:load",
    "any LeRobot PreTrainedPolicy (Hub id or local dir), in-process",
)
FAMILIES.register(
    "openpi", "policy_wrappers.openpi:load", "pi0 / pi0.5 behind openpi's websocket server (ws://HOST:PORT)"
)
FAMILIES.register(
    "openvla-oft",
    "policy_wrappers.openvla:load",
    "OpenVLA-OFT / OpenVLA deploy server (http://HOST:PORT, POST /act)",
)
FAMILIES.register(
    "groot", "policy_wrappers.groot:load", "Isaac-GR00T N1.5/N1.6 ZMQ inference service (tcp://HOST:PORT)"
)
FAMILIES.register(
    "univla",
    "policy_wrappers.served_vla:load_univla",
    "UniVLA (baaivision) LIBERO checkpoint behind scripts/serve/libero_vla.py (ws://HOST:PORT)",
)
FAMILIES.register(
    "rynnvla",
    "policy_wrappers.served_vla:load_rynnvla",
    "RynnVLA-002 LIBERO checkpoint behind scripts/serve/libero_vla.py (ws://HOST:PORT)",
)
FAMILIES.register(
    "standin", "policy_wrappers.standin:load", "CPU stand-ins: oracle, random, noop, or a tiny checkpoint dir"
)

STANDINS: Registry = Registry("stand-in policy")
STANDINS.register(
    "random",
    "policy_wrappers.standin:RandomPolicy",
    "uniform random deltas, reproducible from the episode seed",
)
STANDINS.register("noop", "policy_wrappers.standin:NoopPolicy", "zero motion, gripper open")


def register_standin(name: str, target: str, description: str) -> None:
    """Register ``standin:NAME`` as the class at ``"module:attr"`` (built with no arguments, imported on use).

    The application layer registers stand-ins that live elsewhere (the scenes' privileged oracle:
    ``indgen_vla.app.engine``), so this package never refers to them. Registering the same again is a no-op.
    """
    STANDINS.register(name, target, description)


EXAMPLES = {
    "lerobot": "lerobot:lerobot/smolvla_libero  or  lerobot:./outputs/checkpoints/last/pretrained_model",
    "openpi": "openpi:ws://gpu-box:8000?replan=5",
    "openvla-oft": "openvla-oft:http://gpu-box:8777  or  openvla-oft:http://gpu-box:8000?variant=openvla&unnorm_key=libero_spatial_no_noops",
    "groot": "groot:tcp://gpu-box:5555?api=n1.5",
    "univla": "univla:ws://gpu-box:8000",
    "rynnvla": "rynnvla:ws://gpu-box:8000  or, for a LIBERO-Spatial/Long checkpoint, rynnvla:ws://gpu-box:8000?chunk=10",
    "standin": "standin:oracle | standin:random | standin:noop | standin:PATH_TO_CHECKPOINT",
}


@dataclass(frozen=True)
class ParsedSpec:
    """A spec string split into family, target (URL, Hub id, path or name) and ``?key=value`` options."""

    spec: str
    family: str
    target: str
    options: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.target:
            raise ConfigError(
                f"policy spec {self.spec!r} has nothing after '{self.family}:'; e.g. {EXAMPLES[self.family]}"
            )


# lerobot's policy ``type`` names a user may write where the family goes (``act:ckpt`` for ``lerobot:ckpt``): a hint
LEROBOT_TYPES = frozenset(
    {"act", "diffusion", "pi0", "pi05", "pi0.5", "pi0_fast", "smolvla", "tdmpc", "vqbet", "xvla"}
)


def parse_spec(spec: str) -> ParsedSpec:
    """Split ``family:target[?k=v&...]``; raise ``ConfigError`` / ``UnknownNameError`` with the fix."""
    if not isinstance(spec, str) or not spec.strip():
        raise ConfigError(
            "empty policy spec; use FAMILY:TARGET, e.g. standin:oracle or openpi:ws://HOST:PORT"
        )
    spec = spec.strip()
    family, sep, rest = spec.partition(":")
    if not sep:
        if family in STANDINS:
            raise ConfigError(f"policy spec {spec!r} lacks a family; did you mean 'standin:{family}'?")
        raise ConfigError(
            f"policy spec {spec!r} lacks a family; use one of {', '.join(f + ':' for f in FAMILIES.names())}"
        )
    if family not in FAMILIES:
        if family.lower() in LEROBOT_TYPES and "lerobot" in FAMILIES:
            raise ConfigError(
                f"policy spec {spec!r}: {family!r} is a LeRobot policy type, not a family; load its checkpoint "
                f"with lerobot:{rest or 'HUB_ID_OR_DIR'} (a served model: openpi:ws://HOST:PORT, groot:tcp://...)"
            )
        raise UnknownNameError("policy family", family, FAMILIES.names())
    target, _, query = rest.partition("?")
    try:
        options = dict(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
    except ValueError:
        raise ConfigError(
            f"policy spec {spec!r}: bad options {query!r}; write ?key=value&key2=value2"
        ) from None
    return ParsedSpec(
        redact(spec), family, target.strip(), options
    )  # the name shown masks secrets; options keep them


class Options:
    """Typed access to a spec's options that rejects unknown keys with a did-you-mean."""

    def __init__(self, spec: str, options: Mapping[str, object]):
        self.spec, self._raw, self._used = spec, dict(options), set()

    def _get(self, key: str) -> object | None:
        self._used.add(key)
        return self._raw.get(key)

    def str(self, key: str, default: str | None = None) -> str | None:
        value = self._get(key)
        return default if value is None else str(value)

    def int(self, key: str, default: int | None = None) -> int | None:
        value = self._get(key)
        if value is None:
            return default
        try:
            return int(value)
        except (TypeError, ValueError):
            raise ConfigError(f"policy {self.spec}: option {key}={value!r} must be an integer") from None

    def float(self, key: str, default: float | None = None) -> float | None:
        value = self._get(key)
        if value is None:
            return default
        try:
            return float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"policy {self.spec}: option {key}={value!r} must be a number") from None

    def bool(self, key: str, default: bool | None) -> bool | None:
        value = self._get(key)
        if value is None or value == "auto":
            return default
        if isinstance(value, bool):
            return value
        text = str(value).lower()
        if text in ("1", "true", "yes", "on"):
            return True
        if text in ("0", "false", "no", "off"):
            return False
        raise ConfigError(f"policy {self.spec}: option {key}={value!r} must be 0/1 (or true/false)")

    def choice(self, key: str, choices: tuple[str, ...], default: str | None = None) -> str | None:
        value = self.str(key, default)
        if value is not None and value not in choices:
            raise UnknownNameError(
                f"value for option {key!r} of policy {self.spec}", str(value), list(choices)
            )
        return value

    def fields(self, cls: type, names: Mapping[str, str]) -> dict[str, object]:
        """The options given among ``names`` (field of dataclass ``cls``, or parameter of its ``__init__``,
        -> option), typed by its annotation; absent ones are left out, so each default lives in one place."""
        import dataclasses
        import typing

        hints = typing.get_type_hints(cls if dataclasses.is_dataclass(cls) else cls.__init__)
        out: dict[str, object] = {}
        for name, key in names.items():
            kind = next((t for t in typing.get_args(hints[name]) if t is not type(None)), hints[name])
            getter = {int: self.int, float: self.float, bool: self.bool, str: self.str}[kind]
            value = getter(key, None)
            if value is not None:
                out[name] = value
        return out

    def finish(self) -> None:
        """Raise on any option nobody asked for (a typo would otherwise be silently ignored)."""
        unknown = sorted(set(self._raw) - self._used)
        if unknown:
            raise UnknownNameError(f"option of policy {self.spec}", unknown[0], sorted(self._used))


def _resolve(spec: str, kw: Mapping[str, object]) -> tuple[ParsedSpec, Callable[..., object], Options]:
    """A spec string's parts, its family's loader and its options (``?key=value``, overridden by ``kw``)."""
    parsed = parse_spec(spec)
    return parsed, FAMILIES.load(parsed.family), Options(parsed.spec, {**parsed.options, **kw})


def load_policy(
    spec: str, *, trust_remote_code: bool = False, device: str = "cpu", scene: str | None = None,
    env_spec: EnvSpec | None = None, scene_family: object = None, **kw: object,
):  # fmt: skip
    """Load the policy a spec string names (the engine's and ``indgen serve``'s entry point).

    Extra keyword arguments are spec options (the same as ``?key=value``) and override them. ``scene`` (the
    scene being evaluated) reaches loaders that take it, for scene-dependent defaults (base OpenVLA's unnorm_key);
    ``env_spec`` (the scene family's ``EnvSpec``) and ``scene_family`` (the scene family object itself, opaque here: the
    scenes' own oracle is its family's) reach loaders that take them.
    """
    import inspect

    parsed, loader, options = _resolve(spec, kw)
    params = inspect.signature(loader).parameters
    if env_spec is not None and "env_spec" not in params:  # a LIBERO-only family: refused before it connects
        from policy_wrappers.layouts import layout_for  # lazy: start-up (numpy)

        layout_for(parsed.family, env_spec)
    extra = {"scene": scene} if scene and "scene" in params else {}
    if (
        env_spec is not None and "env_spec" in params
    ):  # the scene's cameras and action size (stand-ins act in it)
        extra["env_spec"] = env_spec
    if scene_family is not None and "scene_family" in params:
        extra["scene_family"] = scene_family
    policy = loader(parsed, options, trust_remote_code=trust_remote_code, device=device, **extra)
    try:
        options.finish()
    except Exception:
        policy.close()
        raise
    if not hasattr(policy, "spec") or not hasattr(policy, "act"):
        raise PolicyError(f"policy {spec}: loader returned {type(policy).__name__}, which lacks spec/act")
    return policy


def preview_policy(
    spec: str, *, device: str = "cpu", env_spec: EnvSpec | None = None, **kw: object
) -> ScenePreview | None:
    """The scene the policy ``spec`` names will ask for, when its family can read it from the policy's files
    without loading it (a module-level ``preview`` beside the family's loader); None otherwise, or on any doubt:
    ``load_policy`` then reports what is wrong. Cheap: no torch, no network."""
    import logging
    import sys

    try:
        parsed, loader, options = _resolve(spec, kw)
        read = getattr(sys.modules[loader.__module__], "preview", None)
        if read is None:
            return None
        return read(parsed, options, device=device, env_spec=env_spec)
    except Exception:  # a guess that cannot be made costs start-up time only, never the run
        logging.getLogger(__name__).debug("no preview of policy %s", spec, exc_info=True)
        return None


def catalog() -> dict[str, list[dict[str, str]]]:
    """Families and stand-ins with descriptions and examples (what ``indgen policies`` prints)."""
    families = [{"name": e.name, "description": e.description, "example": EXAMPLES[e.name]} for e in FAMILIES]
    standins = [{"name": f"standin:{e.name}", "description": e.description} for e in STANDINS]
    return {"families": families, "standins": standins}
