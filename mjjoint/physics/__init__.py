"""Physics terms of the elastic joint: parameter sets and their numba kernels.

Each module holds one term of Ruderman (2012): a frozen, validated parameter dataclass and
small pure ``@njit(cache=True)`` kernels operating on scalars, so that the MuJoCo plugin and
the offline tools evaluate exactly the same equations.
"""
