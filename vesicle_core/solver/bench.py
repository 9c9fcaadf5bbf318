"""``vesicle bench``: time one whole IBM step and its parts against the bare FFT of the same grid.

Parts (medians over repeats, timed round-robin in one process so that the shared machine's speed
drifts hit every column alike):
    fft      rfftn + irfftn of the 3-component grid (the floor of the method)
    forces   membrane forces (bending + area penalty + volume penalty), App. A
    prepare  4-point stencil of every vertex, eqs. (26)-(27)
    spread   eq. (28)
    solve    periodic Stokes incl. its two FFTs, eqs. (21)-(23)
    interp   eqs. (16), (29)
    step     one full time step of the projection scheme as the run loop does it
ratio = step / fft: the whole step relative to the bare FFT.
"""

from __future__ import annotations

import time

import numpy as np


def interleaved_ms(fns, repeats, warmup=1):
    """Median and minimum wall time (ms) of each callable, timed round-robin (one call of each per round) so
    that drifts of the machine's speed hit all of them alike."""
    for _ in range(warmup):
        for fn in fns.values():
            fn()
    ts = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            ts[k].append(time.perf_counter() - t0)
    return ({k: 1e3 * float(np.median(v)) for k, v in ts.items()},
            {k: 1e3 * float(np.min(v)) for k, v in ts.items()})


def bench_case(N, level, backend="numpy", repeats=10, scheme="projection", L=5.0):
    from ..geometry import mesh as M
    from ..model.run_config import RunConfig
    from .integrators import SCHEMES
    from .mobility import IBMSolver
    from .trajectory import State

    m = M.make_vesicle("icosphere", level=level)
    # the kernel coupling with the 4-point kernel, as this benchmark has always timed (its numbers in the docs are
    # of it), whatever the run parameters' defaults (the sharp coupling with the 6-point kernel since they became
    # the recommended method)
    cfg = RunConfig(chi=67.0, N=N, L=L, scheme=scheme, backend=backend, dt=1e-6, coupling="kernel", kernel="peskin4")
    s = IBMSolver(m.faces, m.vertices, cfg)
    be, xp = s.be, s.xp
    X = xp.asarray(m.vertices * 1.001)
    F, geo = s.forces(X)
    st = s.coupler.prepare(X)
    f = s.coupler.spread(F).copy()
    u = s.stokes.velocity(f).copy()
    grid = be.zeros(s.grid.field_shape)
    axes = (1, 2, 3)
    spec = be.rfftn(grid, axes)
    state = State(X=X)
    integ = SCHEMES[scheme](s, cfg.dt)

    def sync(a=None):
        if be.is_gpu:
            xp.cuda.Stream.null.synchronize()
        return a

    def step():
        Fs, g = s.forces(state.X)
        dX = integ.step(state, state.X, Fs, g, cfg.dt, cfg.chi)
        state.X = state.X + dX
        state.step += 1
        sync()

    fns = {
        "fft": lambda: sync(be.irfftn(be.rfftn(grid, axes), s.grid.shape, axes)),
        "forces": lambda: sync(s.forces(X)),
        "prepare": lambda: sync(s.coupler.prepare(X)),
        "spread": lambda: sync(s.coupler.spread(F, st)),
        "solve": lambda: sync(s.stokes.velocity(f)),
        "interp": lambda: sync(s.coupler.interpolate(u, st)),
        "step": step,
    }
    del spec
    out = interleaved_ms(fns, repeats)[0]
    out.update(N=N, vertices=m.n_vertices, edge_over_h=m.quality()["edge_mean"] / (L / N), backend=be.name,
               ratio=out["step"] / out["fft"])
    return out


def main(sizes=(32, 64, 128), levels=(4, 5), backend="numpy", repeats=10):
    cols = ("fft", "forces", "prepare", "spread", "solve", "interp", "step")
    print(f"{'N':>4} {'verts':>6} {'edge/h':>6} " + " ".join(f"{c:>8}" for c in cols) + f" {'step/fft':>8}   (ms)")
    rows = []
    for N in sizes:
        for level in levels:
            r = bench_case(N, level, backend, repeats)
            rows.append(r)
            print(f"{N:>4} {r['vertices']:>6} {r['edge_over_h']:>6.2f} " + " ".join(f"{r[c]:>8.2f}" for c in cols)
                  + f" {r['ratio']:>8.2f}", flush=True)
    return rows
