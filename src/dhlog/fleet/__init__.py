"""Many sessions: batch runs and the comparisons and trends over their results."""
