"""The core layer: protocol, run records, statistics and reports; imports neither scenes nor policies."""
