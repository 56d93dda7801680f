"""Test-suite set-up shared by every test module.

The suite is an entry point like ``tdem``: it makes the same numba threading-layer choice
(OpenMP first, a NUMBA_THREADING_LAYER* setting of yours wins) before any test compiles a
parallel kernel, so the kernels called directly here run on the layer ``tdem`` uses.
"""
from thermal_kernel.threading_layer import prefer_openmp


def pytest_configure(config):
    prefer_openmp()
