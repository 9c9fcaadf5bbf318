"""t_* and l_* on coarse frame grids shifted against each other, from one run with fine frames.

    python benchmarks/t_star_frame_grid.py results/runs/<case>/spectra.nc 5

Every ``stride``-th frame, from each of the ``stride`` offsets, is one coarse frame grid; the per-frame spectra do
not depend on the other frames, so each grid's t_* and l_* are what a run with that output spacing would report
(up to the step lengths, which land on the frames). Prints, per grid, the frame values (argmin of Delta_2) and the
values between the frames (harmonics.t_star_between_frames), and their spread over the grids.
"""

import sys

import numpy as np
import xarray as xr

from vesicle_core.analysis.harmonics import t_star_between_frames, t_star_index


def main(path, stride):
    with xr.open_dataset(path) as sp:
        sp.load()
    t, D2, lt = sp.time.values, sp.Delta_l.values[:, 2], sp.l_star_t.values
    tf, idx, w = t_star_between_frames(t, D2)
    print(f"every frame ({t[1] - t[0]:.4g} apart): frame t_* = {t[t_star_index(t, D2)]:.4f}, "
          f"between frames t_* = {tf:.4f}, l_* = {np.dot(w, lt[list(idx)]):.3f}")
    rows = []
    for off in range(stride):
        k = np.arange(off, t.size, stride)
        i = t_star_index(t[k], D2[k])
        tf, idx, w = t_star_between_frames(t[k], D2[k])
        rows.append((t[k][i], lt[k][i], tf, float(np.dot(w, lt[k][list(idx)]))))
        print(f"offset {off}: frame t_* = {rows[-1][0]:.4f}, l_* = {rows[-1][1]:.3f} | between frames "
              f"t_* = {tf:.4f}, l_* = {rows[-1][3]:.3f}")
    r = np.array(rows)
    print(f"spread over the grids: frame t_* {np.ptp(r[:, 0]):.4f}, l_* {100 * np.ptp(r[:, 1]) / r[:, 1].mean():.2f}%;"
          f" between frames t_* {np.ptp(r[:, 2]):.4f}, l_* {100 * np.ptp(r[:, 3]) / r[:, 3].mean():.2f}%")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 5)
