"""What ``indgen certify`` shows: the progress while the oracle runs, on stderr, and each certificate's table on
stdout (``print_table``).

On a terminal: ``evaluate``'s live display (``indgen_vla.core.reporting.live``), one row per level with the oracle's successes so
far and its verdict once decided, and a total row with the ETA. Piped or logged (rich would print its rows only at
the end): a line when a task starts and one per finished level, so a log shows progress as it happens.
"""

from __future__ import annotations

from indgen_vla.app.certify.certify_levels import level_line
from indgen_vla.core.reporting.live import level_info, level_label, progress_columns
from scenes.certificates import current_oracle_version, level_status, level_verdict
from scenes.family import Scene
from scenes.heldout import basis

_STATUS = {"certified": "[green]certified[/]", "failed": "[red]failed[/]", "insufficient": "insufficient"}


class CertifyDisplay:
    """The progress of one task's certification; ``certify`` calls ``start``, ``episode``, ``level`` and ``log``."""

    def __init__(self, scene: str, task: str, axis: str, console=None):
        from rich.console import Console

        self.scene, self.task, self.axis = scene, task, axis
        self.console = console if console is not None else Console(stderr=True)
        self.live = self.console.is_terminal
        self._progress = None
        self._rows: dict[int, object] = {}  # level -> its rich task
        self._seen: dict[int, int] = {}  # level -> episodes shown so far
        self._done: set[int] = set()
        self._n_max, self._planned = 0, 0

    def __enter__(self) -> CertifyDisplay:
        return self

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.stop()
            self._progress = None

    def log(self, text: str) -> None:
        """A message (reused levels, a replaced certificate): above the live rows, or a plain line."""
        self.console.print(text, soft_wrap=True, markup=False, highlight=False)

    def start(self, levels: list[int], reused: list[dict], n_max: int) -> None:
        """The levels about to run (at most ``n_max`` episodes each) and the rows reused from the certificate."""
        self._n_max = n_max
        where = f"{self.scene}/{self.task}/{self.axis}"
        if not self.live:
            if levels:
                self.log(f"certifying {where}: levels {', '.join(map(str, levels))} (at most {n_max} episodes "
                         "each, stopping a level at its first failure that rules certification out)")  # fmt: skip
            return
        from rich.progress import Progress

        self._progress = Progress(*progress_columns(), console=self.console, transient=False)
        self._progress.start()
        p = self._progress
        self._planned = n_max * len(levels)
        self._total = p.add_task("all episodes", total=self._planned, info=where)
        for row in sorted(reused, key=lambda r: r["level"]):
            p.add_task(level_label(self.axis, int(row["level"])), total=row["n"], completed=row["n"],
                       info=f"reused: {_STATUS.get(row['status'], row['status'])}")  # fmt: skip
        for k in levels:
            self._rows[k] = p.add_task(level_label(self.axis, k), total=n_max, info="")
            self._seen[k] = 0

    def episode(self, level: int, successes: int, n: int) -> None:
        """One more oracle episode of ``level`` finished (``successes`` of ``n`` so far)."""
        if self._progress is None or level in self._done or level not in self._rows:
            return
        self._progress.update(self._rows[level], completed=n, info=level_info(successes, n))
        self._progress.update(self._total, advance=n - self._seen[level])
        self._seen[level] = n

    def level(self, row: dict) -> None:
        """A level decided: its verdict on its row (a level the rule stopped early shrinks the total)."""
        k = int(row["level"])
        if self._progress is None:
            self.log(level_line(self.scene, self.task, self.axis, row))
            return
        if k in self._done or k not in self._rows:
            return
        self._done.add(k)
        n, status = row["n"], _STATUS.get(row["status"], row["status"])
        self._progress.update(
            self._rows[k], total=n, completed=n, info=f"{level_info(row['successes'], n)} {status}"
        )
        self._planned -= self._n_max - n  # the rule stopped the level early: those episodes never run
        self._progress.update(self._total, total=self._planned, advance=n - self._seen[k])
        self._seen[k] = n


def print_table(cert: dict, scene: Scene) -> None:
    """A certificate's levels (of ``scene``'s family): successes, rate, lower bound and verdict."""
    from rich.console import Console
    from rich.table import Table

    rule = cert.get("rule", {})
    current = current_oracle_version(scene)
    oracle = cert.get("oracle") or {}
    table = Table(
        title=f"certification: {cert['scene']}/{cert['task']}, axis {cert['axis']} (step {cert['step']:g} {cert['unit']})",
        caption=f"privileged oracle; certified when the one-sided {rule.get('confidence', 0.95):.0%} Clopper-Pearson "
        f"lower bound >= {cert['threshold']:.0%} (at most {cert.get('episodes')} episodes per level); oracle "
        f"{oracle.get('name', '?').rpartition(':')[2]} v{current}",
    )
    for col in ("level", "param", "successes/n", "rate", "CP lower", "status"):
        table.add_column(col, justify="right")
    for r in cert["levels"]:
        st = level_verdict(r, cert, current)
        if level_status(r) == "certified":
            st += f" ({basis(r)}, block {r.get('block', '?')})"
        table.add_row(
            str(r["level"]), f"{r['param']:g}", f"{r['successes']}/{r['n']}", f"{r['rate']:.0%}",
            f"{r.get('lower_bound', float('nan')):.3f}", st if level_status(r) != "failed" else f"[red]{st}[/red]",
        )  # fmt: skip
    Console().print(table)
