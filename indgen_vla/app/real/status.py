"""Where a real-robot run stands: per-level counts, Wilson CIs, voids, the sequential rule's decisions and the next
episode (what ``indgen real status`` prints, and its ``--json``)."""

from __future__ import annotations

from indgen_vla.app.real.session import Recorder
from indgen_vla.core.stats.metrics import success_rate


def status(rr) -> dict:
    """Per-level counts, Wilson CIs, voids and decisions, and the queue (the ``--json`` of ``real status``)."""
    rec = Recorder(rr)
    state = rec.state()
    seq = rr.sequential(state)
    queue = rr.queue(state)
    levels = []
    for k in rr.levels:
        outs = [e.kind == "success" for (lv, _), e in state.counted.items() if lv == k]
        r = success_rate(sum(outs), len(outs))
        d = seq.decisions.get(k) if seq else None
        levels.append({"level": k, "param": rr.params[k], "unit": rr.axis.unit, "n": r.n, "successes": r.successes,
                       "rate": r.rate if r.n else None, "ci_low": r.ci_low, "ci_high": r.ci_high,
                       "voids": sum(len(v) for (lv, _), v in state.voids.items() if lv == k),
                       "decision": d.verdict if d else (rr.not_run(seq, k) if seq else None)})  # fmt: skip
    nxt = None
    if queue:
        k, i = queue[0]
        nxt = {"level": k, "episode": i, "param": rr.params[k], "setup": rr.axis.level(k).setup,
               "placement": rr.setup.placement(i), "instruction": rr.setup.instruction}  # fmt: skip
    return {"run": str(rr.run.path), "task": rr.task, "axis": rr.axis.name, "ci": "wilson 95%", "levels": levels,
            "queued": len(queue), "next": nxt, "complete": not queue,
            "stopping": rr.mode, "kstar": seq.kstar.get("pos", {}).get("text") if seq else None,
            "caveats": rr.caveats()}  # fmt: skip
