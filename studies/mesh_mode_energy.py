"""What a shape mode costs on a triangle mesh against the continuum (validation.mode_energy.mode_stiffness).

    python studies/mesh_mode_energy.py MESH.nc [MESH.nc ...] [--l-max 16] > numbers.md

For each mesh file (``vesicle mesh``; its vertices are projected onto the unit sphere) and l = 2..l_max: the
second variation of the mesh's bending energy (eq. 25) and area along r = 1 + eps Y_lm at fixed volume, over
kappa (l-1) l (l+1) (l+2) and (l-1)(l+2); mean over m and the range over m. A ratio below 1 means the mesh makes
the mode cheaper: a thermal run on it has larger amplitudes than the continuum formula at the same tension.

Feeds docs/history/thermal.md, "The mesh's own equilibrium, the step, and the noise scheme (2026-12-05)".
"""

from __future__ import annotations

import argparse

import numpy as np
import xarray as xr

from vesicle_core.validation.mode_energy import mode_stiffness


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("meshes", nargs="+")
    ap.add_argument("--l-max", type=int, default=16)
    a = ap.parse_args()
    for path in a.meshes:
        ds = xr.open_dataset(path)
        X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
        ms = mode_stiffness(X, ds.face_node_connectivity.values, a.l_max)
        print(f"{path}: {len(X)} vertices")
        print()
        print("| l | bending / continuum (range over m) | area / continuum (range over m) |")
        print("|---|---|---|")
        for i, l in enumerate(ms.l):
            print(f"| {l} | {ms.bending[i]:.3f} ({ms.bending_range[i, 0]:.3f}-{ms.bending_range[i, 1]:.3f}) "
                  f"| {ms.area[i]:.3f} ({ms.area_range[i, 0]:.3f}-{ms.area_range[i, 1]:.3f}) |")
        print()


if __name__ == "__main__":
    main()
