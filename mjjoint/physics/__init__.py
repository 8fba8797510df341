"""Physics terms of the elastic joint: parameter sets and their numba kernels.

Each module holds one term of Ruderman (2012): a frozen, validated parameter dataclass and
small pure kernels (``jit.kernel``: numba, cached) operating on scalars, so that the MuJoCo
plugin and the offline tools evaluate exactly the same equations.
"""
