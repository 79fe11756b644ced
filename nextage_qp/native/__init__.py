"""Compiled loops (numba) and MuJoCo's warnings: a leaf every layer may use.

The loops: MuJoCo's C library called from the collision rows (:mod:`.kernels`), the shapes' signed distance
(:mod:`.sdf`).
"""
