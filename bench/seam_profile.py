"""Where a walled box loses contacts, by depth (issue 24, docs/packings.md): per layer of d̄/2 at
a depth (the distance of a centre from the nearest wall of the box, in mean diameters) the mean
touching Z of the spheres there and the mean contact radius of their contacts over d̄ (x 1000).
The shell path's frozen band starts at shell_diameters (6 d̄ by default): the seam between the
free shell and the band shows as a dip in Z there, in series with a flux between two walls.

For a shell box (method = "shell": its attribute cell_packing names the periodic cell it copied,
when that file is still there) the spheres of each layer are split
into those YADE moved and those still exactly where the cell put them (the frozen band and the
unloaded interior), and for the moved ones it adds k, their mean number of touching contacts with
unmoved spheres, and c = (Z - k)/2 + k, their constraints per sphere: a contact between two moved
spheres is half a constraint of each, a contact with an unmoved (rigid) one a whole constraint of
the moved sphere (Maxwell's counting; a frictionless jammed packing has c = 3 per sphere).
Measures, asserts nothing.

    .venv/bin/python bench/seam_profile.py PACKING.h5 ...
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from thermal_kernel.packing import read_packing  # noqa: E402

EDGES_D = np.arange(3.0, 9.01, 0.5)


def depth_d(position: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Distance of each centre from the nearest face of the spheres' bounding box, in d̄."""
    lo = (position - radius[:, None]).min(axis=0)
    hi = (position + radius[:, None]).max(axis=0)
    return np.minimum(position - lo, hi - position).min(axis=1) / (2.0 * float(radius.mean()))


def unmoved_mask(position: np.ndarray, radius: np.ndarray, cell_path: Path) -> np.ndarray:
    """The spheres still exactly (to 1e-9 of the period) at a copy of the cell's centres. The
    copies' offset is found from the sphere nearest the box's centre, which the shell path never
    loads, matched to the cell's sphere of the same radius (radii are copied bit for bit)."""
    import h5py
    from scipy.spatial import cKDTree
    with h5py.File(cell_path, "r") as f:
        period = float(f["domain"].attrs["hi"][0] - f["domain"].attrs["lo"][0])
        cell_position = f["particles/position"][:] % period
        cell_radius = f["particles/radius"][:]
    centre = int(np.argmin(np.linalg.norm(position - position.mean(axis=0), axis=1)))
    shift = position[centre] - cell_position[int(np.argmin(np.abs(cell_radius - radius[centre])))]
    distance, _ = cKDTree(cell_position, boxsize=period).query((position - shift) % period)
    return distance < 1e-9 * period


def copied_cell(path: Path) -> Path | None:
    """The periodic cell a shell box copied, if the file it names is still there."""
    import h5py
    with h5py.File(path, "r") as f:
        if f.attrs.get("method") != "shell":
            return None
        cell = Path(str(f.attrs.get("cell_packing", "")))
    return cell if cell.is_file() else None


def profile(path: Path) -> dict[str, np.ndarray]:
    """Per layer of EDGES_D: touching Z and mean contact radius / d̄ of all its spheres; for a
    shell box whose cell is there, also Z, k and c of the moved spheres and Z of the unmoved ones
    (NaN where none)."""
    packing = read_packing(path)
    cell = copied_cell(path)
    position, radius = packing.position, packing.radius
    d_mean = 2.0 * float(radius.mean())
    layer = np.digitize(depth_d(position, radius), EDGES_D) - 1
    touching = packing.overlap > 0
    pair, a = packing.pair[touching], packing.contact_radius[touching]
    n = len(radius)
    z = np.bincount(pair.reshape(-1), minlength=n).astype(float)
    a_sum = np.bincount(pair.reshape(-1), weights=np.repeat(a, 2), minlength=n)
    layers = range(len(EDGES_D) - 1)

    def mean_of(values, keep):
        return np.array([values[keep & (layer == k)].mean() if np.any(keep & (layer == k))
                         else np.nan for k in layers])
    every = np.ones(n, dtype=bool)
    out = dict(z=mean_of(z, every),
               a=np.array([a_sum[layer == k].sum() / z[layer == k].sum() for k in layers])
               / d_mean)
    if cell is not None:
        still = unmoved_mask(position, radius, cell)
        k_rigid = (np.bincount(pair[:, 0], weights=still[pair[:, 1]], minlength=n)
                   + np.bincount(pair[:, 1], weights=still[pair[:, 0]], minlength=n))
        out.update(z_moved=mean_of(z, ~still), k_moved=mean_of(k_rigid, ~still),
                   c_moved=mean_of(0.5 * (z - k_rigid) + k_rigid, ~still),
                   z_unmoved=mean_of(z, still))
    return out


ROWS = [("z", "touching Z", 1.0), ("a", "  contact radius / d̄ x 1000", 1000.0),
        ("z_moved", "  moved: touching Z", 1.0), ("k_moved", "  moved: contacts with unmoved", 1.0),
        ("c_moved", "  moved: constraints c", 1.0), ("z_unmoved", "  unmoved: touching Z", 1.0)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("packings", nargs="+", type=Path)
    args = parser.parse_args(argv)
    print(f"{'depth from the nearest wall (d̄)':34s}" + "".join(f"{e:6.1f}" for e in EDGES_D[:-1]))
    for path in args.packings:
        rows = profile(path)
        for key, title, scale in ROWS:
            if key in rows:
                title = f"{path.parent.name}: {title}" if key == "z" else title
                print(f"{title:34s}" + "".join(f"{scale * v:6.2f}" for v in rows[key]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
