"""tdem's thermal kernel: packing I/O, conductance laws, network assembly and solvers."""
__version__ = "0.1.0"
