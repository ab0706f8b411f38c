"""``indgen budget`` and ``indgen series`` as configs: each holds evaluate's protocol (an ``EvalConfig``) and its own
options, whose fields make the flags (``config_fields.option``). Light (no numpy, no scene): ``indgen --help``
builds the parsers from them."""

from __future__ import annotations

import os
from dataclasses import dataclass

from indgen_vla.app.config_fields import check_types, option
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.core.errors import ConfigError

DEFAULT_DROP = 0.2
DEFAULT_STARTUP_S = 10.0  # no smoke: start-up, report and exit assumed (docs/results/benchmarks/startup.md)
CI_METHODS = ("wilson", "clopper-pearson")


def _numbers(value, kind, flag: str) -> tuple | None:
    """A comma list (the flag's text) or a sequence as a tuple of ``kind``; None stays None."""
    if value is None or isinstance(value, tuple):
        return value
    if not isinstance(value, str):
        return tuple(kind(x) for x in value)
    try:
        return tuple(kind(x) for x in value.split(",") if x.strip())
    except ValueError:
        raise ConfigError(
            f"{flag} takes a comma list, e.g. {'8,16' if kind is int else '0.95,0.9,0.5'}; got {value!r}"
        ) from None


def budget_workers(value) -> tuple[int, ...]:
    """``--workers W[,W...]`` of a budget (default: the number of cores)."""
    return _numbers(value, int, "--workers") or (os.cpu_count() or 1,)


@dataclass(frozen=True, kw_only=True)
class BudgetConfig:
    """What ``indgen budget`` sizes: evaluate's ``protocol`` (its workers the first count, its out unused), the
    worker counts to project, where the costs and the success curve come from, and the lock to write."""

    # evaluate's flags or --config (the command builds it; API: an EvalConfig)
    protocol: EvalConfig = option()
    workers: tuple[int, ...] | None = option(None, "worker counts to project, e.g. 8,16 (default: the number of "
                                             "cores)", metavar="W[,W...]")  # fmt: skip
    timing: str | None = option(None, "a smoke run's directory made on the target box: its manifest's timing and "
                                "its episodes", metavar="RUN")  # fmt: skip
    steps_per_s: float | None = option(None, "without a smoke run: control steps per second of one worker, policy "
                                       "included", type=float)  # fmt: skip
    startup_s: float | None = option(None, "with --steps-per-s: start-up, report and exit seconds (default "
                                     f"{DEFAULT_STARTUP_S:g})", type=float)  # fmt: skip
    assume: tuple[float, ...] | None = option(None, "assumed success rate per |level| 0, 1, 2, ... (every axis and "
                                              "task), e.g. 0.95,0.9,0.5,0.1", metavar="S0,S1,...")  # fmt: skip
    pilot: str | None = option(None, "a pilot run of the protocol: its per-level counts, with their uncertainty, "
                               "as the curve", metavar="RUN")  # fmt: skip
    drop: float = option(DEFAULT_DROP, f"the drop from T0 the paired test should see (default {DEFAULT_DROP:g})",
                         type=float)  # fmt: skip
    ci: str = option(
        "wilson", "the per-level interval report will use (default wilson)", choices=list(CI_METHODS)
    )
    replicates: int = option(
        120, "simulated tasks per curve draw for the adaptive rule (default 120)", type=int
    )
    gpus: int | None = option(None, "GPUs the run holds, for GPU-hours (default 1 with --device cuda, else 0)",
                              type=int)  # fmt: skip
    write: str | None = option(None, "write the pre-registered design to this file", metavar="LOCK")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        object.__setattr__(self, "workers", budget_workers(self.workers))  # "8,16" (a flag) or a sequence
        object.__setattr__(self, "assume", _numbers(self.assume, float, "--assume"))
        _check_protocol(self.protocol, "budget")
        if not self.workers or any(w < 1 for w in self.workers):
            raise ConfigError(f"--workers must be positive counts, e.g. 8,16; got {self.workers}")
        if self.timing and self.steps_per_s is not None:
            raise ConfigError("give --timing RUN or --steps-per-s, not both")
        if self.steps_per_s is not None and not self.steps_per_s > 0:
            raise ConfigError(f"--steps-per-s must be > 0, got {self.steps_per_s}")
        if self.assume is not None and self.pilot:
            raise ConfigError("give --assume or --pilot RUN, not both")
        if not 0 < self.drop < 1:
            raise ConfigError(f"--drop must be in (0, 1), got {self.drop}")
        if self.ci not in CI_METHODS:
            raise ConfigError(f"--ci must be one of {', '.join(CI_METHODS)}, got {self.ci!r}")
        if self.replicates < 1:
            raise ConfigError(f"--replicates must be >= 1, got {self.replicates}")
        if self.gpus is not None and self.gpus < 0:
            raise ConfigError(f"--gpus must be >= 0, got {self.gpus}")


def _check_protocol(protocol: object, command: str) -> None:
    """budget and series run evaluate's protocol: an ``EvalConfig``, as the command line builds it."""
    if not isinstance(protocol, EvalConfig):
        owner = "series'" if command == "series" else f"{command}'s"
        raise ConfigError(f"{owner} protocol must be an EvalConfig, got {type(protocol).__name__}; build it with "
                          "EvalConfig.from_flat(...) or indgen_vla.app.engine.config.config_from_values")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class SeriesConfig:
    """What ``indgen series`` evaluates: every checkpoint of ``roots`` under evaluate's ``protocol`` (its policy
    and out are set per checkpoint), into ``out``; ``follow`` keeps polling a training that still writes them."""

    # evaluate's flags or --config (the command builds it; API: an EvalConfig)
    protocol: EvalConfig = option()
    # ROOT...: a LeRobot training output or checkpoint directories (positional)
    roots: tuple[str, ...] = option()
    out: str = option(help="the series directory (runs/<step>, series.md, series.json, plots)", required=True)
    follow: bool = option(False, "keep polling ROOT for new checkpoints while training runs")
    poll: float = option(60.0, "seconds between two looks with --follow (default 60)", type=float)
    idle_stop: float = option(3600.0, "with --follow: stop after this many seconds without a new checkpoint "
                              "(default 3600)", type=float)  # fmt: skip

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        roots = (self.roots,) if isinstance(self.roots, str | os.PathLike) else self.roots
        object.__setattr__(self, "roots", tuple(os.fspath(r) for r in roots))
        object.__setattr__(self, "out", os.fspath(self.out))
        _check_protocol(self.protocol, "series")
        if not self.roots:
            raise ConfigError("series needs a ROOT: a LeRobot training output or checkpoint directories")
        if not self.out:
            raise ConfigError(
                "--out is required: the series directory (runs/<step>, series.md, series.json, plots)"
            )
        if not self.poll > 0 or not self.idle_stop >= 0:
            raise ConfigError("--poll must be > 0 and --idle-stop >= 0 seconds")
