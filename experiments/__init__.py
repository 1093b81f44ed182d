"""Scripts that produce the tables and figures (see experiments/RESULTS.md)."""
