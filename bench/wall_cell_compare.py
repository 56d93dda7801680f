"""The wall layer at the faces' centres (issue 24, docs/packings.md): per unit area (d̄²) the
centres by distance from the wall in bins of d̄/4 over the first 2 d̄, the spheres touching the
wall, and the fraction of small spheres (r < 0.8 r̄) among the centres within 1 d̄ of it. A
packing.h5 (a walled box: each face's central part, 5 d̄ from its edges, as
tdem_post/wall_layers.py takes it) or a wall cell's .npz (bench/wall_cell_yade.py: both walls).
Measures, asserts nothing.

    .venv/bin/python bench/wall_cell_compare.py PACKING.h5 ... CELL.npz ...
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from thermal_kernel.packing import read_packing  # noqa: E402

BINS_D = np.arange(0.0, 2.01, 0.25)
EDGE_MARGIN_D = 5.0


def box_faces(position, radius, lo, hi):
    """(distance from the face / d̄, radius, central area / d̄²) of each face's central part."""
    d_mean = 2.0 * radius.mean()
    size, position = hi - lo, position - lo
    faces = []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        central = np.all([(position[:, a] > EDGE_MARGIN_D * d_mean)
                          & (position[:, a] < size[a] - EDGE_MARGIN_D * d_mean)
                          for a in others], axis=0)
        area = np.prod([size[a] - 2 * EDGE_MARGIN_D * d_mean for a in others]) / d_mean ** 2
        for distance in (position[:, axis], size[axis] - position[:, axis]):
            faces.append((distance[central] / d_mean, radius[central], area))
    return faces


def cell_faces(path):
    """The same for the two walls of a wall cell (.npz of bench/wall_cell_yade.py)."""
    cell = np.load(path)
    position, radius = cell["position"], cell["radius"]
    d_mean = 2.0 * radius.mean()
    area = float(np.prod(cell["L"])) / d_mean ** 2
    return [((position[:, 2] - float(cell["z0"])) / d_mean, radius, area),
            ((float(cell["z1"]) - position[:, 2]) / d_mean, radius, area)]


def layer_stats(faces, radius_mean):
    """(centres per d̄² by bin, touching spheres per d̄², small fraction within 1 d̄)."""
    counts, touching, area, near_small = np.zeros(len(BINS_D) - 1), 0, 0.0, []
    for distance_d, radius, face_area in faces:
        counts += np.histogram(distance_d, BINS_D)[0]
        area += face_area
        touching += int(np.sum(distance_d * 2.0 * radius_mean < radius))
        near_small.append(radius[distance_d < 1.0] < 0.8 * radius_mean)
    return counts / area, touching / area, float(np.mean(np.concatenate(near_small)))


def main(paths):
    print("packing".ljust(28) + " ".join(f"{a:.2f}-{b:.2f}" for a, b in zip(BINS_D[:-1],
                                                                            BINS_D[1:]))
          + " | touching/d̄² | small within 1 d̄")
    for path in paths:
        if path.endswith(".npz"):
            faces, radius = cell_faces(path), np.load(path)["radius"]
            name = Path(path).stem
        else:
            packing = read_packing(path)
            faces = box_faces(packing.position, packing.radius, packing.domain_lo,
                              packing.domain_hi)
            radius, name = packing.radius, Path(path).parent.name
        per_bin, touching, small = layer_stats(faces, float(radius.mean()))
        print(name[:27].ljust(28) + " ".join(f"{x:9.3f}" for x in per_bin)
              + f" | {touching:11.3f} | {small:.3f}")


if __name__ == "__main__":
    main(sys.argv[1:])
