"""Time the analysis of one snapshot (analysis.shape.analyze_snapshot: eqs. 30-32, the ellipsoid fit and A_p).

Run by hand:  python benchmarks/bench_snapshot.py [--level 5] [--l-max 32] [--repeats 7]
Reports the median wall time per snapshot and its ratio to one volume-centroid evaluation on the same mesh, so
the number travels between machines better than the absolute time (it was ~0.1 s at level 5, l_max = 32, on 2 cores,
when this was a timed unit test; a spectra.nc of 50 frames costs about 50 of these).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402

from vesicle_core.analysis import shape as Sh  # noqa: E402
from vesicle_core.geometry import mesh as M  # noqa: E402
from vesicle_core.geometry import surface as Sf  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_forces import median_time  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, default=5)
    ap.add_argument("--l-max", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args(argv)
    m = M.make_vesicle(level=a.level, axes=(1, 0.8, 1))
    t_snap = median_time(lambda: Sh.analyze_snapshot(m.vertices, m.faces, a.l_max), a.repeats)
    t_ref = median_time(lambda: Sf.volume_centroid(m.vertices, m.faces), a.repeats)
    print(f"level {a.level} ({len(m.faces)} triangles), l_max {a.l_max}: {t_snap:.3f} s per snapshot, "
          f"{t_snap / t_ref:.0f}x one volume centroid")


if __name__ == "__main__":
    main()
