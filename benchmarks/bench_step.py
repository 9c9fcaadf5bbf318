"""Benchmark of one IBM velocity evaluation (Sec. IV B, eqs. 19-23, 28-29) against the bare FFT.

Run by hand (not a test):

    /work/venv/bin/python benchmarks/bench_step.py                  # N = 32, 64, 128, 256
    /work/venv/bin/python benchmarks/bench_step.py --sizes 64 128 --fft-library scipy --dtype float32

For every N and mesh (icosphere level 4: 2562 vertices, level 5: 10242; vesicle radius 1, L = 5)
it times, in the same process, medians over repeats (stages timed round-robin, one call of each per
round, so that drifts of the shared VM's speed affect all columns alike):

    fft      bare round trip: rfftn of the 3-component grid + irfftn (persistent buffers)
    prepare  stencil indices/weights (kernels.stencil + tensor product), once per step
    spread   eq. (28) into a persistent buffer (ibm.Coupler: buffers reused across steps)
    solve    StokesSolver.velocity incl. both FFTs (steady Stokes)
    interp   eqs. (16)/(29)
    total    prepare + spread + solve + interp (one velocity evaluation), and ratio total / fft
    step     the same sequence timed as a whole: the realistic number, because there the FFT
             evicts the caches that the separately timed stages enjoy
    unsteady StokesSolver.step with rho_bar = 1e-6 (exponential update, eq. 23/29) incl. FFTs
    min *    minima over the repeats of fft and step, and their ratio (least disturbed by noise)
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # spinning BLAS threads slow the FFT 5-10x
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import gc  # noqa: E402

import numpy as np  # noqa: E402

from vesicle_core.geometry.mesh import make_vesicle  # noqa: E402
from vesicle_core.solver.backend import get_backend  # noqa: E402
from vesicle_core.solver.bench import interleaved_ms  # noqa: E402
from vesicle_core.solver.ibm import Coupler, Grid  # noqa: E402
from vesicle_core.solver.stokes import StokesSolver  # noqa: E402


def _stages(be, grid, solver, unsteady, cp, ubuf, fbuf, chat, X, F):
    """The timed callables for one grid and mesh: closures over this call's arguments only, so that each
    binds its own size's buffers and mesh (not the loop variables of main) and main can free them."""
    cp.prepare(X)
    f = cp.spread(F)
    u = solver.velocity(f, out=ubuf)

    def bare_fft():
        be.rfftn(fbuf, (1, 2, 3), out=chat)
        be.irfftn(chat, grid.shape, (1, 2, 3), out=ubuf, overwrite_x=True, norm="forward")

    def whole():
        cp.prepare(X)
        ff = cp.spread(F)
        uu = solver.velocity(ff, out=ubuf)
        return cp.interpolate(uu)

    return {
        "fft": bare_fft,
        "prepare": lambda: cp.prepare(X),
        "spread": lambda: cp.spread(F),
        "solve": lambda: solver.velocity(f, out=ubuf),
        "interp": lambda: cp.interpolate(u),
        "step": whole,
        "unsteady": lambda: unsteady.step(f, 1e-6, out=ubuf),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128, 256])
    ap.add_argument("--levels", type=int, nargs="+", default=[4, 5])
    ap.add_argument("--L", type=float, default=5.0)
    ap.add_argument("--dtype", default="float64")
    ap.add_argument("--fft-library", default="auto")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=0, help="0: automatic by N")
    args = ap.parse_args(argv)

    be = get_backend("numpy", dtype=args.dtype, fft_workers=args.workers, fft_library=args.fft_library)
    print(f"backend={be.name} fft_library={be.fft_library} dtype={be.dtype} workers={be.fft_workers} "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    meshes = {}
    for lev in args.levels:
        m = make_vesicle(level=lev)
        e = m.edges()
        meshes[lev] = (m.vertices, float(np.linalg.norm(m.vertices[e[:, 0]] - m.vertices[e[:, 1]], axis=1).mean()))
    rng = np.random.default_rng(0)

    hdr = (f"{'N':>4} {'verts':>6} {'edge/h':>6} | {'fft':>8} {'prepare':>8} {'spread':>8} {'solve':>8} "
           f"{'interp':>8} {'total':>8} {'ratio':>6} | {'step':>8} {'ratio':>6} | {'unsteady':>8} | "
           f"{'min fft':>8} {'min step':>8} {'ratio':>6}")
    print(hdr)
    print("-" * len(hdr))
    for N in args.sizes:
        grid = Grid(N, args.L)
        reps = args.repeats or {32: 40, 64: 15, 128: 7}.get(N, 5)
        solver = StokesSolver(grid, be)
        unsteady = StokesSolver(grid, be, rho_bar=1e-6)
        cp = Coupler(grid, be)
        ubuf = be.empty(grid.field_shape)
        fbuf = be.empty(grid.field_shape)
        fbuf[...] = rng.standard_normal(grid.field_shape)
        chat = be.empty((3,) + grid.spectral_shape, be.complex_dtype)

        for V, edge in meshes.values():
            X = V + 1e-3 * rng.standard_normal(V.shape)
            F = rng.standard_normal(V.shape)
            F -= F.mean(axis=0)
            fns = _stages(be, grid, solver, unsteady, cp, ubuf, fbuf, chat, X, F)
            med, mn = interleaved_ms(fns, reps)
            total = med["prepare"] + med["spread"] + med["solve"] + med["interp"]
            print(f"{N:>4} {len(V):>6} {edge / grid.h:>6.2f} | {med['fft']:>8.2f} {med['prepare']:>8.2f} "
                  f"{med['spread']:>8.2f} {med['solve']:>8.2f} {med['interp']:>8.2f} {total:>8.2f} "
                  f"{total / med['fft']:>6.2f} | {med['step']:>8.2f} {med['step'] / med['fft']:>6.2f} | "
                  f"{med['unsteady']:>8.2f} | {mn['fft']:>8.2f} {mn['step']:>8.2f} {mn['step'] / mn['fft']:>6.2f}",
                  flush=True)
        del solver, unsteady, cp, ubuf, fbuf, chat, fns  # fns: its closures hold the buffers too
        gc.collect()


if __name__ == "__main__":
    main()
