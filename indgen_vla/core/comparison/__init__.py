"""Comparisons between runs, axes and groups of runs: paired exact tests with Holm."""
