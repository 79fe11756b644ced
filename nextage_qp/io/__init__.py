"""Input and output: YAML files, the strict schema base, per-joint values, JSON, output paths."""
