"""``tdem export``: a packing (particles and contacts) to VTK for ParaView, through meshio.

A run's temperatures come from :func:`thermal_kernel.output.read_thermal`, on the packing the
run recorded (checked against its content hash: ``read_run_packing``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from thermal_kernel.atomic import replacing
from thermal_kernel.packing import Packing


def packing_to_vtk(packing: Packing, out_path: Path, temperatures=None) -> Path:
    """Write particles as VTK vertices and contacts as lines in one unstructured grid (.vtu).

    Point data: radius_m, phase, coordination (touching contacts). Cell data (contacts):
    overlap_m, normal_force_n (vertices carry NaN there). In ParaView, use a Glyph filter
    (sphere, scale by radius_m, factor 2) to see the particles. ``temperatures`` = (times,
    (K, N) array) from a run adds ``temperature_k`` (the last output) and one point field
    ``temperature_k_t<k>`` per output time (its time in the name, e.g. ``..._t3_2.5s``)."""
    import meshio

    n = packing.n_particles
    touching = packing.overlap > 0
    coordination = np.bincount(packing.pair[touching].reshape(-1), minlength=n)
    cells = [("vertex", np.arange(n, dtype=np.int64).reshape(-1, 1))]
    nan_n = np.full(n, np.nan)
    cell_data = {"overlap_m": [nan_n], "normal_force_n": [nan_n]}
    # Contacts that cross a periodic boundary would draw across the cell: leave them out.
    direct = np.linalg.norm(packing.position[packing.pair[:, 1]]
                            - packing.position[packing.pair[:, 0]] - packing.branch,
                            axis=1) < 1e-9 * max(1.0, float(packing.radius.max()))
    if packing.n_contacts:
        cells.append(("line", packing.pair[direct]))
        cell_data["overlap_m"].append(packing.overlap[direct])
        cell_data["normal_force_n"].append(packing.normal_force[direct])
    point_data = {"radius_m": packing.radius, "phase": packing.phase.astype(np.int32),
                  "coordination": coordination.astype(np.int32)}
    if temperatures is not None:
        times, temperature = temperatures
        point_data["temperature_k"] = temperature[-1]
        for k, t in enumerate(times):
            point_data[f"temperature_k_t{k}_{t:g}s"] = temperature[k]
    mesh = meshio.Mesh(points=packing.position, cells=cells, point_data=point_data,
                       cell_data=cell_data)
    out_path = Path(out_path)
    with replacing(out_path, keep_suffix=True) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return out_path
