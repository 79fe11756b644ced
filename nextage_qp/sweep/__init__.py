"""Robustness at scale: randomised episodes of a task on a local process pool or on Ray."""

BACKENDS = ("local", "ray")
"""Where a sweep's episodes run: a local process pool, or a Ray cluster."""
