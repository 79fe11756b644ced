"""MuJoCo's C library called from compiled loops (numba), and MuJoCo's warnings: a leaf every layer may use."""
