"""What an M4 fit hands out: summaries from draws, the verdict's checks, the thresholds
table and the per-row curves."""
__all__: list[str] = []
