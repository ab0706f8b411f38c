"""``univla:ws://HOST:PORT`` and ``rynnvla:ws://HOST:PORT`` — UniVLA and RynnVLA-002 LIBERO checkpoints.

Neither upstream ships a server: each evaluates LIBERO in-process (baaivision/UniVLA
``reference/RoboVLMs/eval/libero/evaluate_libero_emu.py``; alibaba-damo-academy/RynnVLA-002
``rynnvla-002/eval_solver_libero_continous_w_state.py``). ``scripts/serve/libero_vla.py``, run inside the model's
own environment, wraps the upstream inference behind openpi's websocket protocol as ``indgen serve`` speaks it
(``policy_wrappers/serve.py``: metadata frame, openpi's LIBERO request keys, ``indgen/reset`` hints at episode
starts). These clients are the openpi client with the families' client-side conventions (``LIBERO_UNIVLA``,
``LIBERO_RYNNVLA``: both cameras flipped at 256, nothing resized, the whole chunk executed); what the model does
to its inputs and outputs (resize, prompt, history, de-normalisation, gripper) stays in the server script; the
RynnVLA client declares ``history_steps=1``, so each request also carries the frames of the env step before it. At
connect the client checks that the server serves its family and the chunk it expects, so a wrong server or a
Spatial/Long RynnVLA checkpoint (10 actions per query) without ``?chunk=10`` is one line, not a silent mismatch.
"""

from __future__ import annotations

from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError
from policy_wrappers.openpi import INDGEN_SERVER, OpenpiConfig, OpenpiPolicy
from policy_wrappers.remote import REMOTE_OPTIONS
from policy_wrappers.transforms import LIBERO_RYNNVLA, LIBERO_UNIVLA, Conventions

CONVENTIONS = {"univla": LIBERO_UNIVLA, "rynnvla": LIBERO_RYNNVLA}
SERVER = "scripts/serve/libero_vla.py"


@dataclass(frozen=True, kw_only=True)
class ServedConfig(OpenpiConfig):
    """An openpi-protocol endpoint serving one of ``CONVENTIONS``'s families."""

    model: str

    def __post_init__(self) -> None:
        if self.model not in CONVENTIONS:
            raise ConfigError(f"{self.url}: model must be one of {sorted(CONVENTIONS)}, got {self.model!r}")
        super().__post_init__()

    def family_conventions(self) -> Conventions:
        return CONVENTIONS[self.model]


class ServedVLAPolicy(OpenpiPolicy):
    """The openpi client, checked at connect against ``scripts/serve/libero_vla.py``'s metadata."""

    server = f"{SERVER} (in the model's environment)"

    def __init__(self, name: str, config: ServedConfig):
        super().__init__(name, config)
        try:
            self._check_server()
        except Exception:
            self.close()
            raise

    def _check_server(self) -> None:
        meta, model, url = self.metadata, self.config.model, self.config.url
        if meta.get("server") != INDGEN_SERVER or meta.get("family") != model:
            said = (
                f"family={meta.get('family')!r}"
                if meta.get("server") == INDGEN_SERVER
                else "a plain openpi server"
            )
            raise ConfigError(
                f"policy {self.spec.name}: {url} is {said}, not {model}; start `python {SERVER} {model} ...` "
                "in the model's environment (docs/policies.md)"
            )
        served = meta.get("chunk_size")
        if served != self.spec.chunk_size:
            raise ConfigError(
                f"policy {self.spec.name}: the served checkpoint predicts {served} actions per query, not "
                f"{self.spec.chunk_size}; pass ?chunk={served}"
            )


class UniVLAPolicy(ServedVLAPolicy):
    family = "univla"


class RynnVLAPolicy(ServedVLAPolicy):
    family = "rynnvla"
    history_steps = 1  # his_2: the frames of the env step before each query (the engine renders that step)


OPTIONS = {"api_key": "api_key", **REMOTE_OPTIONS}  # ServedConfig field -> spec option (openpi's)
CLASSES = {"univla": UniVLAPolicy, "rynnvla": RynnVLAPolicy}


def _load(model: str, parsed, options) -> ServedVLAPolicy:
    cls = CLASSES[model]
    config = ServedConfig(url=cls.url_from(parsed), model=model, **options.fields(ServedConfig, OPTIONS))
    return cls(parsed.spec, config)


def load_univla(parsed, options, *, trust_remote_code: bool = False, device: str = "cpu") -> ServedVLAPolicy:
    """``univla:ws://HOST:PORT[?api_key=&replan=&timeout=..]``: baaivision/UniVLA behind ``SERVER``."""
    return _load("univla", parsed, options)


def load_rynnvla(parsed, options, *, trust_remote_code: bool = False, device: str = "cpu") -> ServedVLAPolicy:
    """``rynnvla:ws://HOST:PORT[?chunk=10&..]``: RynnVLA-002 behind ``SERVER``."""
    return _load("rynnvla", parsed, options)
