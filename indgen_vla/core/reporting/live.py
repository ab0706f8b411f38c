"""The live progress display's look, shared by ``evaluate`` and ``certify``: one row per level, a total row.

On a terminal both commands show rich's live rows on stderr (a level's success so far, the total's ETA); ``rich``
loads only when a display starts.
"""

from __future__ import annotations


def progress_columns() -> tuple:
    """The columns of every row: description, bar, done/planned, the level's info text, the time left."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn

    return (TextColumn("{task.description:<22}"), BarColumn(bar_width=24), MofNCompleteColumn(),
            TextColumn("{task.fields[info]}"), TimeRemainingColumn())  # fmt: skip


def level_label(axis: str, level: int) -> str:
    """A level's row name, e.g. ``pick_y L+2``."""
    return f"{axis} L{level:+d}"


def level_info(successes: int, finished: int, errors: int = 0) -> str:
    """Success so far at one level, e.g. ``success 3/4`` (+ errors when any)."""
    text = f"success {successes}/{finished}" if finished else ""
    return text + (f" [red]errors {errors}[/]" if errors else "")
