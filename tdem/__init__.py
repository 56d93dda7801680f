"""tdem: thermal DEM on real packings (command line and orchestration)."""
from thermal_kernel import __version__

__all__ = ["__version__"]
