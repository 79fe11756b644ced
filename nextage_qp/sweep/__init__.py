"""Robustness at scale: randomised episodes of a task on a local process pool or on Ray."""
