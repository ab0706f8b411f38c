"""The ``--check-policy`` trigger of ``indgen real record``: joins the real-robot protocol manager
(``indgen_vla.app.real``, which imports no policy code) to the policy registry, for
``indgen real record RUN --check-policy SPEC`` (``indgen_vla.app.cli.real`` hands it over).

The policy itself runs in the user's stack (their robot loop is the server's client); what our client does is
check that the server answers (the family's handshake: openpi's metadata frame, GR00T's ``ping``, a TCP connect
to an OpenVLA deploy server) once when the session starts and again when each episode starts, then send the
episode's reset where the protocol has one (GR00T N1.6's ``reset`` endpoint; openpi and OpenVLA servers keep no
episode state). A server that does not answer stops the episode from starting, with one line saying why.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from indgen_vla.app.real.trigger import EpisodeContext, TriggerError
from indgen_vla.core.errors import ConfigError, PolicyError
from policy_wrappers.specs import load_policy


class PolicyCheck:
    """The ``--check-policy`` trigger: the policy ``spec`` loads (and so answers) now, and before each episode."""

    name = "policy"

    def __init__(self, spec: str):
        self.spec = spec
        try:
            # a remote family connects and shakes hands here: fails in one line
            self.policy = load_policy(spec)
        except ConfigError as e:  # a bad SPEC: name the option it came from
            raise ConfigError(f"--check-policy {spec}: {e}") from None

    def describe(self, ctx: EpisodeContext) -> str:
        return f"  policy : {self.spec} (checked and reset with seed {ctx.seed} when the episode starts)"

    def start(self, ctx: EpisodeContext, write: Callable[[str], None]) -> dict:
        t0 = time.monotonic()
        try:
            ping = getattr(self.policy, "ping", None)  # remote clients; an in-process policy is always there
            if ping is not None:
                ping()
            self.policy.reset(ctx.instruction, ctx.seed)
        except PolicyError as e:
            raise TriggerError(f"policy check failed, the episode was not started: {e}") from None
        return {
            "spec": self.spec,
            "answered": True,
            "reset": True,
            "seconds": round(time.monotonic() - t0, 3),
        }

    def close(self) -> None:
        self.policy.close()
