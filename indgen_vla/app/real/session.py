"""``indgen real record``: the operator's keyboard session, and its one-shot form for scripts.

Plain ``input()`` and ``print()`` (works over ssh, in tmux, in a pseudo-terminal): the session shows the next
episode (level, the set-up change from the last episode, the instruction), takes the verdict, journals it at once
(``store``), rebuilds ``episodes.parquet``, and prints the level's running rate with n and its Wilson CI and, for
``--adaptive`` runs, what the sequential rule decided and what to run next.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.section import SECTION, write_section
from indgen_vla.app.real.store import (
    FAILURE_HELP,
    JOURNAL,
    OPERATOR_FAILURES,
    Entry,
    State,
    append_entry,
    now,
    read_journal,
    rebuild,
    recording_lock,
    records,
    replay,
    undone_lines,
)
from indgen_vla.app.real.trigger import (
    FIELDS,
    VIDEO_SUFFIXES,
    EpisodeContext,
    Trigger,
    TriggerError,
    check_template,
    echo,
    fill,
    summary_line,
)
from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.runs.records import EPISODES, SECTIONS
from indgen_vla.core.stats.metrics import success_rate
from indgen_vla.core.stats.sprt import UNTIL_FAILURE, Decision, UntilFailure

PROMPT = "outcome [s f v u q ?]> "
START_PROMPT = "start the episode [Enter], or s f v u q ?> "  # with a trigger, before it ran
BACK = "Enter alone: back to the outcome, nothing recorded"
NOT_ZERO = (
    "the command did not exit 0: if the episode did not run as planned, type v with why, or r to run it again"
)
AGAIN_PROMPT = "outcome [s f v u q ? r]> "  # with a trigger, after it ran (r: run it again)
RUN_HELP = """\
  Enter (or r)        start the episode: {what}"""
HELP = """\
  s [note]            success
  f [mode] [note]     failure; mode = 1-5 or its name (asked if left out; Enter alone there backs out)
  v [reason]          void: does not count, the episode is re-queued (reason asked if left out, as above)
  u                   undo the last verdict (asks to confirm)
  q                   quit (everything recorded is saved; run the same command to resume)
  a note may name a video: 'video=PATH' or a path ending in .mp4"""


@dataclass(frozen=True)
class Verdict:
    """A parsed outcome: what the operator (or a script) says about one episode."""

    kind: str  # success | failure | void
    failure: str = ""
    reason: str = ""
    note: str = ""
    video: str = ""


def parse_outcome(spec: str) -> Verdict:
    """The script form: ``success``, ``failure``, ``failure:MODE`` or ``void:REASON``."""
    kind, _, rest = spec.strip().partition(":")
    if kind == "success" and not rest:
        return Verdict("success")
    if kind == "failure":
        mode = rest.strip()
        if mode and mode not in OPERATOR_FAILURES:
            raise ConfigError(
                f"--outcome failure:{mode}: unknown failure mode; use one of {', '.join(OPERATOR_FAILURES)}"
            )
        return Verdict("failure", failure=mode)
    if kind == "void":
        if not rest.strip():
            raise ConfigError("--outcome void needs a reason, e.g. --outcome 'void:robot e-stop'")
        return Verdict("void", reason=rest.strip())
    raise ConfigError(f"--outcome {spec!r}: use success, failure[:MODE] or void:REASON")


def _split_video(words: list[str]) -> tuple[str, str]:
    video, rest = "", []
    for w in words:
        if w.startswith("video="):
            video = w[len("video=") :]
        elif w.lower().endswith(VIDEO_SUFFIXES) and not video:
            video = w
        else:
            rest.append(w)
    return " ".join(rest), video


def failure_mode(token: str) -> str | None:
    """'4' or 'misplaced' -> 'misplaced'; None if it is neither."""
    if token.isdigit() and 1 <= int(token) <= len(OPERATOR_FAILURES):
        return OPERATOR_FAILURES[int(token) - 1]
    return token if token in OPERATOR_FAILURES else None


class Recorder:
    """Journal-backed recording of one real run (shared by the interactive and the one-shot form)."""

    def __init__(self, rr: RealRun, operator: str = "", video_pattern: str | None = None):
        self.rr = rr
        self.operator = operator or rr.manifest["real"].get("operator", "")
        self.video_pattern = video_pattern
        if video_pattern is not None:
            check_template(video_pattern, "--video-pattern", tuple(f for f in FIELDS if f != "video"))
        self.path = rr.run.path

    def state(self) -> State:
        return replay(read_journal(self.path), self.rr.axis.name)

    def sync(self, force: bool = True) -> State:
        """Rebuild ``episodes.parquet`` and the report section from the journal; unless forced, only what is
        older than the journal (missing, or a process was killed between a journal line and its rebuild)."""
        state = self.state()
        journal, view, section = self.path / JOURNAL, self.path / EPISODES, self.path / SECTIONS / SECTION
        mtime = journal.stat().st_mtime_ns if journal.exists() else -1

        def stale(p) -> bool:
            return not p.exists() or p.stat().st_mtime_ns <= mtime

        if journal.exists() and (force or stale(view)):
            rebuild(self.rr.run, records(state, self.rr.manifest, self.rr.seeds, self.rr.params))
        if force or stale(section):
            write_section(self.rr, state)
        return state

    def context(self, state: State, level: int, episode: int) -> EpisodeContext:
        """The episode's fields (``--episode-command`` and ``--video-pattern`` templates, trigger env vars)."""
        rr = self.rr
        ctx = EpisodeContext(run=str(self.path), axis=rr.axis.name, task=rr.task, level=level, param=rr.params[level],
                             unit=rr.axis.unit, episode=episode, attempt=len(state.voids.get((level, episode), ())),
                             seed=rr.seeds[episode], instruction=rr.setup.instruction,
                             placement=rr.setup.placement(episode), policy=rr.manifest["policy"], video="")  # fmt: skip
        if not self.video_pattern:
            return ctx
        values = {k: v for k, v in vars(ctx).items() if k != "video"}
        return dataclasses.replace(ctx, video=fill(self.video_pattern, values, "--video-pattern"))

    def record(
        self, level: int, episode: int, v: Verdict, wall_s: float = 0.0, trigger: dict | None = None
    ) -> Entry:
        """Journal one verdict for a queued episode, then rebuild the Parquet view. The video is the operator's,
        else the one the episode command printed, else ``--video-pattern``'s."""
        entries = read_journal(self.path)
        state = replay(entries, self.rr.axis.name)
        queue = self.rr.queue(state)
        if (level, episode) not in queue:
            nxt = f"level {queue[0][0]} episode {queue[0][1]}" if queue else "nothing: the run is complete"
            raise RunDirError(f"level {level} episode {episode} is not waiting to be run (next: {nxt})")
        trigger = trigger or {}
        video = (
            v.video
            or trigger.get("command", {}).get("video", "")
            or self.context(state, level, episode).video
        )
        entry = Entry(seq=(entries[-1].seq if entries else 0) + 1, kind=v.kind, axis=self.rr.axis.name, level=level,
                      episode=episode, failure=v.failure, reason=v.reason, note=v.note, video=video,
                      operator=self.operator, time=now(), wall_s=round(wall_s, 3), trigger=trigger)  # fmt: skip
        append_entry(self.path, entry)
        self.sync()
        return entry

    def undo(self, seq: int | None = None) -> Entry | None:
        """Cancel a verdict still in force with a new journal line: the latest (None when there is none), or journal
        line ``seq``, found without replaying the journal (the way out of one that records an episode twice, which
        no session can open)."""
        entries = read_journal(self.path)
        if seq is None:
            target = replay(entries, self.rr.axis.name).last
            if target is None:
                return None
        else:
            target = next((e for e in entries if e.seq == seq), None)
            last = entries[-1].seq if entries else 0
            why = (f"the journal has no line {seq} (lines 1-{last})" if target is None
                   else f"journal line {seq} is {'an undo' if target.kind == 'undo' else 'undone already'}")  # fmt: skip
            if target is None or target.kind == "undo" or seq in undone_lines(entries):
                raise RunDirError(f"{self.path}: {why}; give the line of a verdict in force (each "
                                  "'saved:' line ends with its journal line)")  # fmt: skip
        append_entry(self.path, Entry(seq=entries[-1].seq + 1, kind="undo", axis=target.axis, level=target.level,
                                      episode=target.episode, undo=target.seq, operator=self.operator, time=now()))  # fmt: skip
        self.sync()
        return target

    # ------------------------------------------------------------------ what the operator reads
    def level_line(self, state: State, level: int) -> str:
        """The level's running rate with n, Wilson CI and the task it covers (never pooled)."""
        outs = [e.kind == "success" for (k, _), e in state.counted.items() if k == level]
        r = success_rate(sum(outs), len(outs))
        voids = sum(len(v) for (k, _), v in state.voids.items() if k == level)
        head = f"level {level} ({self.rr.axis.param_text(level)}): "
        if not r.n:
            rate = "no episodes counted yet"
        else:
            rate = (f"{r.successes}/{r.n} success = {100 * r.rate:.0f} % (n = {r.n}, 95 % Wilson CI "
                    f"{100 * r.ci_low:.0f}-{100 * r.ci_high:.0f} %)")  # fmt: skip
        return head + rate + f"; task {self.rr.task}" + (f"; {voids} voided" if voids else "")

    def decision_lines(self, state: State, level: int) -> list[str]:
        """Adaptive runs: the level's verdict under the sequential rule and where k* stands."""
        seq = self.rr.sequential(state)
        if seq is None:
            return []
        rule, d = self.rr.rule, seq.decisions.get(level)
        out = []
        if isinstance(rule, UntilFailure):
            out += until_failure_lines(rule, level, d)
        elif d is not None:
            if d.verdict == "broken":
                out.append(
                    f"DECIDED: level {level} is broken (S < γ = {rule.gamma}) after {d.episodes} episodes"
                )
            elif d.verdict == "intact":
                out.append(
                    f"DECIDED: level {level} is intact (S ≥ γ = {rule.gamma}) after {d.episodes} episodes"
                )
            elif d.verdict == "undetermined":
                out.append(f"level {level} reached the cap of {rule.max_episodes} episodes undecided "
                           f"(the fixed-design rule applies: rate {'<' if d.rate < rule.gamma else '≥'} γ)")  # fmt: skip
            else:
                out.append(
                    f"level {level}: not decided yet; the rule looks again at {d.next_boundary} episodes"
                )
        status = seq.kstar.get("pos", {})
        if seq.done and isinstance(rule, UntilFailure):
            out.append(f"until-failure: every level it needs has its trials; {status.get('text', '')}")
        elif seq.done:
            out.append(
                f"adaptive ({self.rr.mode}): every level it needs is decided; {status.get('text', '')}"
            )
        return out

    def episode_lines(self, state: State, level: int, episode: int, position: tuple[int, int],
                      check: bool = False) -> list[str]:  # fmt: skip
        """The block shown before an episode: which, what to change, where things start, what to say. The first
        one of a resumed session, and the one after an undo, spell the set-up out (the scene may have changed)."""
        a, s = self.rr.axis, self.rr.setup
        prev = state.live[-1].level if state.live else None
        if prev is None:
            change = f"set up level {level}: {a.level(level).setup}"
        elif prev == level and check:
            change = f"check level {level} is set up (as at the last verdict): {a.level(level).setup}"
        elif prev == level:
            change = f"no change (level {level} as before: {a.param_text(level)})"
        else:
            change = f"CHANGE level {prev} -> {level}: {a.level(level).setup}"
        voids = len(state.voids.get((level, episode), ()))
        done, left = position
        lines = ["", "-" * 78,
                 f"episode {episode} of level {level} ({a.name} = {a.param_text(level)})"
                 + (f", re-run after {voids} void(s)" if voids else "") + f"   [{done} counted, {left} queued]",
                 f"  set-up : {change}"]  # fmt: skip
        if s.placements:
            lines.append(f"  start  : {s.placement(episode)}")
        lines.append(f'  prompt : "{s.instruction}"')
        return lines


def until_failure_lines(rule: UntilFailure, level: int, d: Decision | None) -> list[str]:
    """The paper's design: a level's trials so far, or, once they are all in, whether the run goes on."""
    if d is None:
        return []
    if not d.final:
        return [
            f"level {level}: {d.episodes} of {rule.max_episodes} trials; the next level waits for the rest"
        ]
    r = success_rate(d.successes, d.n)
    head = (f"level {level} done: {d.successes}/{d.n} = {100 * r.rate:.0f} % (95 % Wilson CI "
            f"{100 * r.ci_low:.0f}-{100 * r.ci_high:.0f} %)")  # fmt: skip
    if rule.stops(d):
        return [f"{head} < γ = {rule.gamma:g}: the run stops here (the paper's until-failure design; an observed "
                "break, not a statistically decided one)"]  # fmt: skip
    return [f"{head} ≥ γ = {rule.gamma:g}: on to the next level"]


def record_once(rr: RealRun, verdict: Verdict, episode: tuple[int, int] | None = None, operator: str = "",
                video_pattern: str | None = None) -> tuple[Entry, list[str]]:  # fmt: skip
    """The script form: journal one verdict for the next queued episode (or the one named), say what follows."""
    rec = Recorder(rr, operator, video_pattern)
    with recording_lock(rec.path):
        state = rec.sync(force=False)
        queue = rr.queue(state)
        if not queue:
            raise RunDirError(f"{rec.path}: every episode the plan needs is recorded; nothing to record")
        level, ep = episode if episode is not None else queue[0]
        entry = rec.record(level, ep, verdict)
        state = rec.state()
        lines = [_saved(entry), rec.level_line(state, level), *rec.decision_lines(state, level)]
        queue = rr.queue(state)
        lines.append(f"next: level {queue[0][0]} episode {queue[0][1]}" if queue else "run complete")
    return entry, lines


def undo_line(rr: RealRun, seq: int, operator: str = "") -> tuple[Entry, Entry | None]:
    """Cancel journal line ``seq`` (a verdict or void still in force) with a new undo line, without replaying the
    journal first: the way out of one that records an episode twice, which no session can open. Returns the line
    undone and the verdict its episode still counts (the other of a pair), if any."""
    rec = Recorder(rr, operator)
    with recording_lock(rec.path):
        target = rec.undo(seq)
        return target, rec.state().counted.get((target.level, target.episode))


def _verdict_text(e: Entry) -> str:
    """A verdict line's episode, outcome, note, video and command exit, as the operator reads it."""
    what = {"success": "success", "failure": f"failure ({e.failure or 'mode not given'})",
            "void": f"VOID ({e.reason}): re-queued"}[e.kind]  # fmt: skip
    extra = "".join(f"; {k} {v}" for k, v in (("note", e.note), ("video", e.video)) if v)
    if "command" in e.trigger:
        extra += f"; command exit {e.trigger['command']['exit_code']}"
    return f"level {e.level} episode {e.episode} {what}{extra}"


def _saved(e: Entry) -> str:
    return f"saved: {_verdict_text(e)} (journal line {e.seq})"


def resume_line(entries: list[Entry]) -> str | None:
    """A resumed session first says what the journal last holds, so an operator whose session died while an
    episode was on screen knows whether that verdict was saved."""
    if not entries:
        return None
    e = entries[-1]
    what = (f"undo of line {e.undo} (level {e.level} episode {e.episode})" if e.kind == "undo"
            else _verdict_text(e))  # fmt: skip
    return (f"resuming: the journal's last line is {e.seq}, {what}, at {e.time or 'an unknown time'}; a verdict "
            "typed after it and never shown as 'saved' was not recorded")  # fmt: skip


def start_episode(triggers: Sequence[Trigger], ctx: EpisodeContext, say: Callable[[str], None],
                  write: Callable[[str], None]) -> dict | None:  # fmt: skip
    """Run each trigger in order (policy check, then command); None when one could not start the episode."""
    info = {}
    for t in triggers:
        try:
            info[t.name] = t.start(ctx, write)
        except TriggerError as e:
            say(str(e))
            say("fix it and press Enter to try again, or type a verdict (e.g. v server down) to go on")
            return None
    say(summary_line(info))
    c = info.get("command", {})
    if c.get("interrupted") or c.get("exit_code", 0) != 0:  # a crashed eval loop: not a verdict yet
        say(NOT_ZERO)
    return info


def interactive(rr: RealRun, operator: str = "", video_pattern: str | None = None,
                ask: Callable[[str], str] = input, say: Callable[[str], None] = print,
                triggers: Sequence[Trigger] = (), write: Callable[[str], None] = echo) -> bool:  # fmt: skip
    """Run the keyboard session until the plan is complete (True) or the operator quits (False). With
    ``triggers`` the operator starts each episode with Enter (``write`` shows the command's output)."""
    rec = Recorder(rr, operator, video_pattern)
    with recording_lock(rec.path):
        state = rec.sync(force=False)
        say(f"recording {rec.path}: task {rr.task} \"{rr.setup.instruction}\", axis {rr.axis.name} levels "
            f"{rr.levels[0]}..{rr.levels[-1]}, {rr.order}, "
            + (f"until-failure ({rr.episodes} per level until the first level below γ)" if rr.mode == UNTIL_FAILURE
               else f"adaptive {rr.mode} (at most {rr.episodes} per level)" if rr.mode else f"{rr.episodes} per level")
            + f"; operator {rec.operator or 'not named'}. Type ? for help.")  # fmt: skip
        if (resume := resume_line(read_journal(rec.path))) is not None:
            say(resume)
        check = bool(state.live)  # resumed: spell the set-up out once
        while True:
            queue = rr.queue(state)
            if not queue:
                say("run complete: every episode the plan needs is recorded.")
                return True
            level, ep = queue[0]
            for line in rec.episode_lines(state, level, ep, (len(state.counted), len(queue)), check):
                say(line)
            check = False
            ctx = rec.context(state, level, ep)
            for t in triggers:
                say(t.describe(ctx))
            shown = time.monotonic()
            verdict, started, runs = None, None, 0
            while verdict is None:
                prompt = PROMPT if not triggers else AGAIN_PROMPT if started else START_PROMPT
                try:
                    verdict = _read_verdict(ask(prompt).strip(), rec, ask, say, triggers, started is None)
                except EOFError:  # Ctrl-D: leave like q
                    say("")
                    verdict = "quit"
                if verdict == "quit":
                    say(
                        f"stopped; {len(state.counted)} counted episodes are saved. Resume: indgen real record {rec.path}"
                    )
                    return False
                if verdict == "run":
                    runs += 1  # the journal keeps the last start and how many there were
                    started = start_episode(triggers, ctx, say, write) or started
                    if started:
                        started["starts"] = runs
                    verdict = None
                if verdict == "undo":  # the scene may show the next episode's set-up: spell the set-up out
                    state, check = rec.state(), True
                    break
            if verdict in (None, "undo"):
                continue
            entry = rec.record(level, ep, verdict, wall_s=time.monotonic() - shown, trigger=started)
            state = rec.state()
            say(_saved(entry))
            say(rec.level_line(state, level))
            for line in rec.decision_lines(state, level):
                say(line)


def _read_verdict(line: str, rec: Recorder, ask, say, triggers: Sequence[Trigger] = (), fresh: bool = True):
    """One operator line -> a Verdict, "run", "undo", "quit", or None (shown help / not understood: ask again)."""
    if not line:
        return "run" if triggers and fresh else None
    word, *rest = line.split()
    word = word.lower()
    if word in ("q", "quit", "exit"):
        return "quit"
    if word in ("r", "run") and triggers:
        return "run"
    if word in ("?", "h", "help"):
        if triggers:
            say(RUN_HELP.format(what=", then ".join(t.name for t in triggers)))
        say(HELP)
        return None
    if word in ("u", "undo"):
        last = rec.state().last
        if last is None:
            say("nothing to undo")
            return None
        if (
            ask(f"undo level {last.level} episode {last.episode} ({last.kind})? [y/N]> ").strip().lower()
            != "y"
        ):
            say("kept")
            return None
        rec.undo()
        say(f"undone: level {last.level} episode {last.episode} {last.kind}; it is queued again")
        return "undo"
    if word in ("s", "success"):
        note, video = _split_video(rest)
        return Verdict("success", note=note, video=video)
    if word in ("f", "failure", "fail"):
        mode = failure_mode(rest[0]) if rest else None
        if mode is not None:
            rest = rest[1:]
        while mode is None:
            say(
                "failure mode: "
                + "  ".join(f"{j} {m}" for j, m in enumerate(OPERATOR_FAILURES, 1))
                + f"  (0 = not sure; {BACK})"
            )
            for m in OPERATOR_FAILURES:
                say(f"    {m}: {FAILURE_HELP[m]}")
            answer = ask("mode> ").split()
            if not answer:  # 'f' typed by mistake: nothing is journaled
                say("back: nothing recorded")
                return None
            first, *more = answer
            mode = "" if first == "0" else failure_mode(first)
            if mode is None:
                say(f"not a failure mode: {first!r}")
            else:
                rest = [*rest, *more]  # "4 toppled the stack": the mode, then a note
        note, video = _split_video(rest)
        return Verdict("failure", failure=mode, note=note, video=video)
    if word in ("v", "void"):
        reason = " ".join(rest)
        if not reason.strip():
            reason = ask(f"void reason (why it does not count; {BACK})> ").strip()
        if not reason:  # 'v' typed by mistake
            say("back: nothing recorded")
            return None
        return Verdict("void", reason=reason)
    say(f"not understood: {line!r}; type s, f, v, u, q or ? for help")
    return None
