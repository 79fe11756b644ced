"""Scenes: scene files and overrides, objects declared as data, building them with MjSpec, checks, friction."""
