"""``RemotePolicy``: what the openpi, GR00T and OpenVLA clients share (URL, timeouts, reconnect, error mapping).

Each client keeps only its wire format. Every transport fault becomes a ``PolicyConnectionError`` (the engine
pauses and reconnects) and drops the connection, so the next call opens a new one; everything the server
says is wrong becomes a ``PolicyError`` naming the policy.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar
from urllib.parse import urlsplit

from indgen_vla.core.errors import ConfigError, IndgenError, PolicyConnectionError, PolicyError
from indgen_vla.core.protocol.interface import PolicySpec
from policy_wrappers.image_tools import GRIPPER_MODES
from policy_wrappers.transforms import MIN_IMAGE_SIZE, Conventions

# RemoteConfig field -> spec option, shared by the remote families
REMOTE_OPTIONS = {
    "timeout_s": "timeout",
    "connect_timeout_s": "connect_timeout",
    "chunk_size": "chunk",
    "replan_steps": "replan",
    "image_size": "size",
    "render_size": "render",
    "flip_180": "flip",
}


def check_url(spec: str, target: str, schemes: tuple[str, ...], default_port: int) -> tuple[str, str, int]:
    """Parse ``scheme://host:port`` for a remote family; return (scheme, host, port)."""
    example = f"{schemes[0]}://127.0.0.1:{default_port}"
    parts = urlsplit(target)
    if parts.scheme not in schemes:
        got = f"scheme {parts.scheme + '://'!r}" if parts.scheme else "no scheme"
        raise ConfigError(
            f"policy spec {spec!r}: {got}; this family takes {' or '.join(s + '://' for s in schemes)}, e.g. {example}"
        )
    try:
        port = parts.port or default_port
    except ValueError:
        raise ConfigError(f"policy spec {spec!r}: bad port in {target!r}; e.g. {example}") from None
    if not parts.hostname:
        raise ConfigError(f"policy spec {spec!r}: no host in {target!r}; e.g. {example}")
    if parts.path not in ("", "/"):
        raise ConfigError(
            f"policy spec {spec!r}: unexpected path {parts.path!r}; give only {schemes[0]}://HOST:PORT"
        )
    return parts.scheme, parts.hostname, port


def join_url(scheme: str, host: str, port: int) -> str:
    """``scheme://host:port`` with IPv6 hosts bracketed."""
    return f"{scheme}://[{host}]:{port}" if ":" in host else f"{scheme}://{host}:{port}"


@dataclass(frozen=True, kw_only=True)
class RemoteConfig:
    """Where a policy server listens, how long to wait for it, and the spec's overrides of the family's
    conventions (None keeps the family's value; ``conventions`` is the result)."""

    url: str
    timeout_s: float = 60.0  # per request
    connect_timeout_s: float = 10.0  # opening the connection and the handshake
    chunk_size: int | None = None
    replan_steps: int | None = None
    render_size: int | None = None  # what the engine renders
    image_size: int | None = None  # what is sent (the resize step's size)
    flip_180: bool | None = None
    gripper: str | None = None  # one of image_tools.GRIPPER_MODES
    conventions: Conventions = field(init=False)

    def __post_init__(self) -> None:
        if self.timeout_s <= 0 or self.connect_timeout_s <= 0:
            raise ConfigError(
                f"{self.url}: timeouts must be positive, got {self.timeout_s:g}/{self.connect_timeout_s:g}"
            )
        if any(size is not None and size < MIN_IMAGE_SIZE for size in (self.image_size, self.render_size)):
            raise ConfigError(
                f"{self.url}: image sizes must be >= {MIN_IMAGE_SIZE}, got {self.image_size}/{self.render_size}"
            )
        if self.gripper is not None and self.gripper not in GRIPPER_MODES:
            raise ConfigError(f"{self.url}: gripper must be one of {GRIPPER_MODES}, got {self.gripper!r}")
        conventions = self.family_conventions().override(
            flip=self.flip_180,
            size=self.image_size,
            render=self.render_size,
            gripper=self.gripper,
            **self.more_overrides(),
        )
        object.__setattr__(self, "conventions", conventions)

    def family_conventions(self) -> Conventions:
        """The upstream conventions these options override (``policy_wrappers.transforms``)."""
        raise NotImplementedError

    def more_overrides(self) -> dict:
        """Family-specific ``Conventions.override`` arguments (base OpenVLA's crop)."""
        return {}

    def chunking(self) -> tuple[int, int]:
        """(chunk size, replan steps): the options, else the family's."""
        return self.conventions.chunking(self.chunk_size, self.replan_steps)


class RemotePolicy:
    """Base of the clients of a policy server: subclasses set the class constants, ``_drop`` and the wire."""

    family: ClassVar[str]
    schemes: ClassVar[tuple[str, ...]]
    default_port: ClassVar[int]
    server: ClassVar[str]  # what to start when nothing listens, e.g. "the openpi server"

    def __init__(self, spec: PolicySpec, config: RemoteConfig):
        self.spec, self.config = spec, config

    @classmethod
    def url_from(cls, parsed, default_port: int | None = None) -> str:
        """The spec target as a normalised URL (default port filled in, IPv6 bracketed)."""
        port = cls.default_port if default_port is None else default_port
        return join_url(*check_url(parsed.spec, parsed.target, cls.schemes, port))

    def fail(self, message: str) -> PolicyError:
        """A ``PolicyError`` naming this policy."""
        return PolicyError(f"policy {self.spec.name}: {message}")

    def lost(self, message: str) -> PolicyConnectionError:
        """Drop the connection; a ``PolicyConnectionError`` naming this policy (the next call reconnects)."""
        self._drop()
        return PolicyConnectionError(f"policy {self.spec.name}: {message}")

    def _drop(self) -> None:
        """Close the connection, if any; the next call opens a new one."""

    def _map_error(self, error: BaseException, connecting: bool) -> IndgenError | None:
        """A client library's own exception -> ours (None: let the generic mapping decide)."""
        return None

    @contextlib.contextmanager
    def transport(
        self, what: str = "", *, connecting: bool = False, timeout_s: float | None = None
    ) -> Iterator[None]:
        """Map transport faults raised inside to one-line errors, dropping the connection on each."""
        url = self.config.url
        if timeout_s is None:
            timeout_s = self.config.connect_timeout_s if connecting else self.config.timeout_s
        try:
            yield
        except IndgenError:
            raise
        except Exception as e:
            mapped = self._map_error(e, connecting)
            if mapped is not None:
                if isinstance(mapped, PolicyConnectionError):
                    self._drop()
                raise mapped from None
            if isinstance(e, ConnectionRefusedError):
                raise self.lost(f"connection refused at {url}; is {self.server} running?") from None
            if isinstance(e, TimeoutError) and not connecting:
                raise self.lost(
                    f"no reply from {url}{what} within {timeout_s:g}s; is {self.server} running?"
                ) from None
            if isinstance(e, socket.gaierror):  # a typo in the host, or a name this machine cannot resolve
                raise self.lost(
                    f"cannot resolve the host of {url} ({e.strerror or e}); check the host name in the spec, or "
                    "give the server's IP address"
                ) from None
            if isinstance(e, OSError | EOFError):
                if connecting:
                    raise self.lost(f"cannot reach {url}: {e or type(e).__name__}") from None
                raise self.lost(f"connection to {url} lost: {type(e).__name__}: {e}") from None
            raise

    def reset(self, instruction: str, seed: int | None = None) -> None:
        pass

    def ping(self) -> None:
        """Check that the server answers now (the family's handshake); raise ``PolicyConnectionError`` if not.
        Used by ``indgen real record --check-policy`` before each real-robot episode."""
        raise NotImplementedError

    def close(self) -> None:
        self._drop()
