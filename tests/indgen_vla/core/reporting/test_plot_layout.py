"""The failure-mode, progress and series plots show every legend entry inside the figure, clear of the panels."""

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from indgen_vla.core.comparison.series_report import series_figures, write_series
from indgen_vla.core.reporting.failures import MODES, failures_figure
from indgen_vla.core.reporting.partial_credit import STAGES, progress_figure
from tests.indgen_vla.core.reporting.test_report import make_run


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


def _legend_clear(fig, expected: list[str]) -> None:
    """Every ``expected`` entry in the figure's one legend and inside the figure; the legend clear of every panel
    with its title and labels."""
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    (legend,) = fig.legends
    texts = {t.get_text(): t.get_window_extent(renderer) for t in legend.get_texts()}
    assert all(e in texts for e in expected), list(texts)
    box = fig.bbox
    for text, ext in texts.items():
        assert box.x0 <= ext.x0 and ext.x1 <= box.x1 and box.y0 <= ext.y0 and ext.y1 <= box.y1, text
    own = legend.get_window_extent(renderer)
    for ax in fig.axes:
        b = ax.get_tightbbox(renderer)
        covers = own.x0 < b.x1 - 1 and b.x0 < own.x1 - 1 and own.y0 < b.y1 - 1 and b.y0 < own.y1 - 1
        assert not covers, "the legend covers a panel, its title or labels"


@pytest.mark.parametrize("make", [failures_figure, progress_figure], ids=["failures", "progress"])
@pytest.mark.parametrize("runs", [1, 2])
def test_every_legend_entry_is_inside_the_figure_and_clear_of_the_panels(make, runs):
    fig = make(
        [_run(f"h-only / lerobot:checkpoints/act_pick_place_human_{i}") for i in range(runs)], "pick_y"
    )
    _legend_clear(fig, list(MODES) if make is failures_figure else [f"{i} {s}" for i, s in enumerate(STAGES)])


def test_series_plots_keep_their_legends_off_the_curves_and_say_n_per_point(tmp_path):
    """Five checkpoints over seven levels: the legend's eight entries sit beside the panel, not over L0 at 1.0."""

    def levels(k: int) -> dict:
        return {
            -3: (k // 3, 10),
            -2: (k // 2, 10),
            -1: (k, 10),
            0: (10, 10),
            1: (k, 10),
            2: (k // 2, 10),
            3: (1, 10),
        }

    runs = [(s, make_run(tmp_path / str(s), levels(k), regime=str(s)).path)
            for s, k in ((1000, 1), (2000, 4), (3000, 6), (4000, 8), (5000, 10))]  # fmt: skip
    series = write_series(runs, tmp_path / "out")
    (success, fig), (kstar, fig2) = series_figures(series)
    assert (success, kstar) == ("pick_y_success.png", "pick_y_kstar.png")
    _legend_clear(fig, [f"L{k}" for k in range(-3, 4)] + ["γ"])
    assert "n = 10 per point" in fig.axes[0].get_title()
    _legend_clear(fig2, ["k* (+)", "k* (−)"])


def _axis(tmp_path, counts):
    from indgen_vla.core.reporting.summary import summarize

    run = make_run(tmp_path, counts)
    return summarize(run.episodes(), run.manifest, 0.2)["axes"]["pick_y"]


def test_a_run_without_a_rate_plots_its_levels_and_says_why_it_is_empty(tmp_path):
    """Every level below the data floor (n = 3): the success plot's ticks are the levels run and its text says why
    nothing is drawn, in the PNG and in the SVG (before: a blank axis ticked -0.04..0.04, and '0' alone)."""
    from matplotlib.figure import Figure

    from indgen_vla.core.reporting.figures import NO_RATE, draw_curves
    from indgen_vla.core.reporting.svg_plot import axis_svg

    a = _axis(tmp_path, {-1: (3, 3), 0: (3, 3), 1: (0, 3)})
    ax = Figure().subplots()
    assert draw_curves(ax, [("run", a)], 0.2)[0] == []
    assert list(ax.get_xticks()) == [-1, 0, 1] and [t.get_text() for t in ax.texts] == [NO_RATE]
    svg = axis_svg("run", a, "pick_y", 0.2)
    assert all(f">{line}</text>" in svg for line in NO_RATE.split("\n"))
    assert all(f'text-anchor="middle">{k}</text>' in svg for k in (-1, 0, 1))


def test_the_svg_caption_wraps_a_long_label_inside_the_figure(tmp_path):
    """The run's label, n and tasks, then the key: lines of at most CAPTION_CHARS that together hold the whole label,
    each inside the figure (before: one 200-character line cut at both edges)."""
    import re

    from indgen_vla.core.reporting.svg_plot import CAPTION_CHARS, axis_svg

    a = _axis(tmp_path, {-1: (5, 6), 0: (6, 6), 1: (1, 6)})
    label = "h-only / lerobot:checkpoints/act_pick_place_human_trained_on_a_great_many_demonstrations_v2"
    svg = axis_svg(label, a, "pick_y", 0.2, "wilson")
    height = int(re.search(r'height="(\d+)"', svg).group(1))
    caption = re.findall(
        r'<text x="[\d.]+" y="([\d.]+)" text-anchor="middle" font-size="10">([^<]*)</text>', svg
    )
    assert len(caption) >= 3 and all(len(t) <= CAPTION_CHARS and float(y) < height - 3 for y, t in caption)
    assert " ".join(t for _, t in caption).startswith(
        f"{label} (n = 6 per level; task t) shaded: Wilson 95 % CI"
    )
    assert caption[-1][1].endswith("ringed: k* (first level below γ)")
