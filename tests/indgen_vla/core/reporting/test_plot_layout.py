"""The failure-mode and progress plots show every legend entry inside the figure, clear of bars and titles."""

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from indgen_vla.core.reporting.failures import MODES, failures_figure
from indgen_vla.core.reporting.partial_credit import STAGES, progress_figure


def _run(label: str) -> tuple[str, dict]:
    """Seven levels in which every failure mode and every progress stage occurs, under a long label."""
    levels = []
    for k in range(-3, 4):
        failures = {m: 1 + (i + k) % 3 for i, m in enumerate(MODES)}
        stages = {s: 1 + (i - k) % 2 for i, s in enumerate(STAGES)}
        n = sum(stages.values())
        mean = sum(i * c for i, c in enumerate(stages.values())) / n
        levels.append(
            {"level": k, "failures": failures, "progress": {"stages": stages, "n": n, "mean": mean}}
        )
    return label, {"levels": levels, "pooled_tasks": ["milk"]}


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 - 1 and b.x0 < a.x1 - 1 and a.y0 < b.y1 - 1 and b.y0 < a.y1 - 1


@pytest.mark.parametrize("make", [failures_figure, progress_figure], ids=["failures", "progress"])
@pytest.mark.parametrize("runs", [1, 2])
def test_every_legend_entry_is_inside_the_figure_and_clear_of_the_panels(make, runs):
    fig = make(
        [_run(f"h-only / lerobot:checkpoints/act_pick_place_human_{i}") for i in range(runs)], "pick_y"
    )
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box = fig.bbox
    (legend,) = fig.legends
    entries = [t.get_text() for t in legend.get_texts()]
    expected = [m for m in MODES] if make is failures_figure else [f"{i} {s}" for i, s in enumerate(STAGES)]
    assert all(e in entries for e in expected), entries
    for text in legend.get_texts():
        ext = text.get_window_extent(renderer)
        assert box.x0 <= ext.x0 and ext.x1 <= box.x1 and box.y0 <= ext.y0 and ext.y1 <= box.y1, (
            text.get_text()
        )
    own = legend.get_window_extent(renderer)
    for ax in fig.axes:
        assert not _overlaps(own, ax.get_tightbbox(renderer)), (
            "the legend covers a panel, its title or labels"
        )
