"""Pictures of a packing: a vertical section through the centre and a 3-D view."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from thermal_kernel.atomic import savefig_atomic
from thermal_kernel.packing import Packing


def section_circles(packing: Packing, axis: int = 1, at: float | None = None):
    """Circles cut by the plane x_axis = at: (centre in the plane's two other coordinates,
    radius sqrt(r^2 - d^2), particle index) for every sphere the plane crosses."""
    if at is None:
        at = 0.5 * (packing.domain_lo[axis] + packing.domain_hi[axis])
    d = packing.position[:, axis] - at
    hit = np.abs(d) < packing.radius
    keep = [a for a in range(3) if a != axis]
    centres = packing.position[hit][:, keep]
    radii = np.sqrt(packing.radius[hit] ** 2 - d[hit] ** 2)
    return centres, radii, np.flatnonzero(hit)


def plot_packing(packing: Packing, out_path, title: str | None = None) -> Path:
    """Save a PNG: left, the section through the domain centre normal to y, discs coloured by
    coordination (touching contacts); right, all particle centres in 3-D."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    n = packing.n_particles
    touching = packing.overlap > 0
    z = np.bincount(packing.pair[touching].reshape(-1), minlength=n)
    centres, radii, idx = section_circles(packing, axis=1)
    fig = plt.figure(figsize=(11, 5.5))
    ax = fig.add_subplot(1, 2, 1)
    patches = [Circle((c[0] * 1e3, c[1] * 1e3), r * 1e3) for c, r in zip(centres, radii)]
    coll = PatchCollection(patches, cmap="viridis", edgecolor="k", linewidth=0.3)
    coll.set_array(z[idx].astype(float))
    coll.set_clim(0, max(1, int(np.percentile(z, 99))))
    ax.add_collection(coll)
    lo, hi = packing.domain_lo * 1e3, packing.domain_hi * 1e3
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[2], hi[2])
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_title("section y = centre (colour: contacts per particle)")
    fig.colorbar(coll, ax=ax, shrink=0.8, label="coordination Z")
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    sc = ax3.scatter(*(packing.position.T * 1e3), c=packing.position[:, 2], s=2, cmap="coolwarm")
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.set_zlabel("z (mm)")
    ax3.set_box_aspect(np.maximum(packing.domain_hi - packing.domain_lo, 1e-12))
    ax3.set_title(f"{n} particles")
    del sc
    p = packing.attrs.get("pressure_pa", float("nan"))
    fig.suptitle(title or (f"{Path(packing.path).name}: "
                           f"phi = {packing.attrs['solid_fraction']:.3f}, "
                           f"Z = {2 * touching.sum() / n:.2f}"
                           + (f", p = {p / 1e5:.3g} bar" if np.isfinite(p) else "")))
    fig.tight_layout()
    out_path = Path(out_path)
    try:
        savefig_atomic(fig, out_path, dpi=120, format="png")
    finally:
        plt.close(fig)
    return out_path
