"""MuJoCo coupling: the engine plugin that injects the joint physics, written in numba."""
