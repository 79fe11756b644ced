"""Collision-free joint paths: the planner's collision world, OMPL's RRT-Connect, shortcutting, dense checks."""
