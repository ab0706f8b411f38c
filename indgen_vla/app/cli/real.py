"""``indgen real plan|record|status``: a passthrough subcommand whose sub-parsers and handlers are here; the work
is the real-robot protocol's (``indgen_vla.app.real``: plan, session, store, status). ``record --check-policy`` gets
the policy registry's trigger (``indgen_vla.app.real_policy``), since that package never imports a policy."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import TYPE_CHECKING

from indgen_vla.app.cli.options import IndgenParser, add_passthrough  # one-line errors, as every command
from indgen_vla.app.config_fields import add_flags, from_args
from indgen_vla.core.errors import ConfigError

if TYPE_CHECKING:
    from indgen_vla.app.real.trigger import Trigger


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen real`` parses its own arguments (``main``)."""
    add_passthrough(sp, "real", "real-robot protocol with an operator: plan | record | status")


def main(args: argparse.Namespace) -> int:
    """Parse ``args.rest`` with the real-robot sub-parsers and run the one named, with ``--check-policy``."""
    from indgen_vla.app.real_policy import PolicyCheck  # lazy: start-up (the policy registry)

    return run(args.rest, policy_check=PolicyCheck)


def build_parser() -> argparse.ArgumentParser:
    from indgen_vla.app.real.design import PLAN_FLAGS, RealPlanConfig  # lazy: start-up
    from indgen_vla.app.real.trigger import FIELDS  # lazy: start-up

    p = IndgenParser(
        prog="indgen real",
        description="The paper's real-robot protocol (§5.3): plan the levels of a physical axis, record the "
        "operator's verdicts episode by episode, then 'indgen report' / 'indgen compare' the run directory.",
    )
    sp = p.add_subparsers(dest="cmd", required=True)
    pl = sp.add_parser("plan", help="write a run directory and the operator's protocol for a real axis")
    add_flags(pl, RealPlanConfig, PLAN_FLAGS)
    rc = sp.add_parser("record", help="take the operator's verdicts (keyboard session, or one --outcome)")
    rc.add_argument("run", metavar="RUN", help="run directory written by 'indgen real plan'")
    rc.add_argument("--outcome", default=None, help="record one verdict and exit: success, failure[:MODE], "
                    "void:REASON (for the next queued episode unless --episode)")  # fmt: skip
    rc.add_argument("--episode", default=None, metavar="LEVEL:INDEX", help="with --outcome: which episode")
    rc.add_argument("--undo", type=int, default=None, metavar="LINE",
                    help="cancel the verdict on that journal line and exit (the session's 'u' cancels the last)")  # fmt: skip
    rc.add_argument("--note", default="", help="with --outcome: a free-text note")
    rc.add_argument("--video", default="", help="with --outcome: path of the episode's video")
    rc.add_argument(
        "--video-pattern",
        default=None,
        help="video path filled in when none is given, e.g. /data/{axis}_L{level}_e{episode}.mp4",
    )
    rc.add_argument("--operator", default="", help="who judges (default: the one named at plan time)")
    rc.add_argument(
        "--episode-command",
        default=None,
        metavar="TEMPLATE",
        help="run this command when the operator starts each episode (Enter), e.g. 'python my_eval.py --level "
        "{level} --seed {seed} --instruction {instruction}'; fields: " + ", ".join(FIELDS) + " (also as "
        "INDGEN_* env vars); its exit code, log and a printed video=PATH go into the journal",
    )
    rc.add_argument(
        "--check-policy",
        default=None,
        metavar="SPEC",
        help="check that the policy server SPEC answers (openpi:ws://..., groot:tcp://..., openvla-oft:http://...) "
        "at the start and before each episode, and reset it there",
    )
    rc.add_argument("--no-report", action="store_true", help="do not write the report when the run completes")
    st = sp.add_parser("status", help="per-level counts, decisions and the next episode of a real run")
    st.add_argument("run", metavar="RUN", help="run directory written by 'indgen real plan'")
    st.add_argument("--json", action="store_true", help="machine-readable output")
    return p


def run(argv: list[str], policy_check: Callable[[str], Trigger] | None = None) -> int:
    """``indgen real ARGV...``; ``policy_check`` builds the ``--check-policy`` trigger (``main`` passes
    ``indgen_vla.app.real_policy.PolicyCheck``)."""
    ns = build_parser().parse_args(argv)
    if ns.cmd == "record":
        return _record(ns, policy_check)
    return {"plan": _plan, "status": _status}[ns.cmd](ns)


def _plan(ns: argparse.Namespace) -> int:
    from indgen_vla.app.api import real_plan  # lazy: start-up
    from indgen_vla.app.real.design import PROTOCOL, RealPlanConfig  # lazy: start-up

    path = real_plan(from_args(RealPlanConfig, ns, command="real plan"))
    print((path / PROTOCOL).read_text(), end="")
    print(f"planned {path}; next: indgen real record {path}")
    return 0


def _episode(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    try:
        level, index = (int(x) for x in text.split(":"))
    except ValueError:
        raise ConfigError(f"--episode {text!r} must look like LEVEL:INDEX, e.g. 2:7") from None
    return level, index


def _triggers(ns: argparse.Namespace, rr, policy_check) -> list[Trigger]:
    """The policy check (first: no command starts while the server is down), then the episode command."""
    from indgen_vla.app.real.trigger import EpisodeCommand  # lazy: start-up

    command = EpisodeCommand(ns.episode_command, str(rr.run.path)) if ns.episode_command is not None else None
    out: list[Trigger] = []
    if ns.check_policy is not None:
        if policy_check is None:
            raise ConfigError("--check-policy needs the policy registry; run it as 'indgen real record ...'")
        out.append(policy_check(ns.check_policy))
    return [*out, command] if command else out


def _record(ns: argparse.Namespace, policy_check: Callable[[str], Trigger] | None = None) -> int:
    from indgen_vla.app.real.design import RealRun  # lazy: start-up
    from indgen_vla.app.real.session import (  # lazy: start-up
        Verdict,
        interactive,
        parse_outcome,
        record_once,
        undo_line,
    )

    rr = RealRun.open(ns.run)
    if ns.undo is not None:
        if ns.outcome is not None:
            raise ConfigError("--undo cancels a verdict and --outcome records one: give one of them")
        e, kept = undo_line(rr, ns.undo, ns.operator)
        then = f"it keeps line {kept.seq}'s {kept.kind}" if kept else "it is queued again"
        print(f"undone: journal line {ns.undo}, level {e.level} episode {e.episode} {e.kind}; {then}")
        return 0
    if ns.outcome is None:
        if ns.episode or ns.note or ns.video:
            raise ConfigError(
                "--episode, --note and --video go with --outcome (the keyboard session asks for them)"
            )
        triggers = _triggers(ns, rr, policy_check)
        try:
            complete = interactive(rr, ns.operator, ns.video_pattern, triggers=triggers)
        finally:
            for t in triggers:
                t.close()
    else:
        if ns.episode_command is not None or ns.check_policy is not None:
            raise ConfigError("--episode-command and --check-policy start episodes in the keyboard session; "
                              "with --outcome, run the episode yourself first")  # fmt: skip
        v = parse_outcome(ns.outcome)
        v = Verdict(v.kind, v.failure, v.reason, ns.note, ns.video)
        _, lines = record_once(rr, v, _episode(ns.episode), ns.operator, ns.video_pattern)
        print("\n".join(lines))
        complete = lines[-1] == "run complete"
    if complete and not ns.no_report:
        from indgen_vla.core.reporting.report import write_run_report  # lazy: start-up

        write_run_report(rr.run, (rr.plan.get("adaptive") or {}).get("gamma", 0.2))
        print(
            f"report: {rr.run.path / 'report.md'} (summary.json, plots/); compare runs with 'indgen compare'"
        )
    return 0


# the sequential rule's verdict for a level it has not settled yet, as ``real status`` prints it (``--json``: raw)
_DECISION_TEXT = {"continue": "deciding (more episodes needed)"}


def _status(ns: argparse.Namespace) -> int:
    from indgen_vla.app.real.design import RealRun  # lazy: start-up
    from indgen_vla.app.real.status import status  # lazy: start-up

    s = status(RealRun.open(ns.run))
    if ns.json:
        print(json.dumps(s, indent=2))
        return 0
    for line in s["caveats"]:  # first: what this plan can never show
        print(line.replace("**", ""))
    print(f"{s['run']}: task {s['task']}, axis {s['axis']} (95 % Wilson CIs, one task, not pooled)")
    for r in s["levels"]:
        rate = f"{r['successes']}/{r['n']} = {100 * r['rate']:.0f} % [{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]" if r["n"] else "no episodes"  # fmt: skip
        dec = f"  {_DECISION_TEXT.get(r['decision'], r['decision'])}" if r["decision"] else ""
        # only an undo below it leaves counts here
        if r["n"] and r["decision"] in ("not reached", "not needed"):
            dec += f" ({r['n']} recorded before an undo re-opened a lower level)"
        print(
            f"  level {r['level']} ({r['param']:g} {r['unit']}): {rate}, n = {r['n']}, voids {r['voids']}{dec}"
        )
    if s["kstar"] and any(r["n"] for r in s["levels"]):  # before the first episode there is nothing to locate
        print(f"  {s['stopping']}: {s['kstar']}")
    nx = s["next"]
    print(
        f"next: level {nx['level']} episode {nx['episode']} ({s['queued']} queued)" if nx else "run complete"
    )
    return 0
