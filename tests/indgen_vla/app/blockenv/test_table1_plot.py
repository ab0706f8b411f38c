"""The BlockEnv Table 1 plot: every method in a legend clear of the curves, the episodes behind each point."""

import json
from pathlib import Path

from indgen_vla.app.blockenv.reproduce import figure
from tests.indgen_vla.core.reporting.test_plot_layout import _legend_clear


def test_blockenv_table1_plot_keeps_its_legend_off_the_curves_and_says_n():
    """The committed Table 1 reproduction (9 methods): the legend beside the panel, n per point in the title."""
    table = json.loads((Path(__file__).parents[4] / "docs/results/blockenv_table1.json").read_text())
    fig = figure(table, 0.2)
    _legend_clear(fig, [*table, "γ = 0.2"])
    assert "n = 300 per point" in fig.axes[0].get_title()
