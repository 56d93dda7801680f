"""Where a walled box loses contacts, by depth (issue 24, docs/packings.md): per layer of d̄/2 at
a depth (the distance of a centre from the nearest wall of the box, in mean diameters) the mean
touching Z of the spheres there and the mean contact radius of their contacts over d̄ (x 1000).
The shell path's frozen band starts at shell_diameters (6 d̄ by default): the seam between the
free shell and the band shows as a dip in Z there, in series with a flux between two walls.
Measures, asserts nothing.

    .venv/bin/python bench/seam_profile.py PACKING.h5 ...
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from thermal_kernel.packing import read_packing  # noqa: E402

EDGES_D = np.arange(3.0, 9.01, 0.5)


def profile(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(touching Z, mean contact radius / d̄) of the spheres in each layer of EDGES_D."""
    packing = read_packing(path)
    position, radius = packing.position, packing.radius
    d_mean = 2.0 * float(radius.mean())
    lo = (position - radius[:, None]).min(axis=0)
    hi = (position + radius[:, None]).max(axis=0)
    depth = np.minimum(position - lo, hi - position).min(axis=1) / d_mean
    touching = packing.overlap > 0
    pair, a = packing.pair[touching], packing.contact_radius[touching]
    z = np.bincount(pair.reshape(-1), minlength=len(radius)).astype(float)
    a_sum = np.bincount(pair.reshape(-1), weights=np.repeat(a, 2), minlength=len(radius))
    layer = np.digitize(depth, EDGES_D) - 1
    z_mean = np.array([z[layer == k].mean() for k in range(len(EDGES_D) - 1)])
    a_mean = np.array([a_sum[layer == k].sum() / z[layer == k].sum()
                       for k in range(len(EDGES_D) - 1)]) / d_mean
    return z_mean, a_mean


def main(paths: list[str]) -> int:
    print(f"{'depth from the nearest wall (d̄)':34s}" + "".join(f"{e:6.1f}" for e in EDGES_D[:-1]))
    for path in paths:
        z, a = profile(Path(path))
        name = Path(path).parent.name
        print(f"{name + ': touching Z':34s}" + "".join(f"{v:6.2f}" for v in z))
        print(f"{'  contact radius / d̄ x 1000':34s}" + "".join(f"{1000 * v:6.2f}" for v in a))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
