"""summary.json, report.md and figures from run directories, and the black-box regime."""
