"""One step of the inextensible scheme with the recommended discretisation (config/config.yaml's run block): the
membrane forces, the harmonic tension's CG solve (a Stokes solve per iteration), the step's linearisation strain and
the quality mesh ALE (vesicle_core.solver.integrators.Inextensible.step).

The state is that of a run a few steps into the stretching flow at S = 2224 (chi = 268.2, Delta = 0.116): set-up
takes the bending limit (Arnoldi) and three steps, so the tension's warm start and the harmonic space's area rates
rho_l are a run's own. Each timed call takes the next step from that same saved state, so every call does the same
work; the CG iterations it takes are recorded as ``track_cg_iterations``.
"""

import copy

# modules, not their classes: asv would collect RunConfig.time_scale as a benchmark
from vesicle_core.model import run_config
from vesicle_core.solver import mobility, schemes, step_size, trajectory

from .common import DTYPES, NS, L, mesh_for

CHI = 268.2  # S = 2224 at Delta = 0.116: the fastest-wrinkling case of the default sweep
RECOMMENDED = dict(scheme="inextensible", tension_space="harmonic", mesh_ale="quality", coupling="sharp",
                   kernel="bao6", dt="power")
WARM_STEPS = 3


class InextensibleStep:
    """One adaptive step (forces + Integrator.step) on the N^3 grid with its N-matched mesh, per grid dtype."""

    params = (NS, DTYPES)
    param_names = ["N", "dtype"]
    timeout = 300
    # set-up (the bending limit and three steps) costs ~10 steps: one process per parameter set, 3-7 samples
    rounds = 1
    repeat = (3, 7, 60.0)
    number = 1

    def setup(self, N, dtype):
        m = mesh_for(N)
        cfg = run_config.RunConfig(chi=CHI, N=N, L=L, dtype=dtype, backend="numpy", fft_workers=1, **RECOMMENDED)
        self.solver = solver = mobility.IBMSolver(m.faces, m.vertices, cfg)
        xp = solver.xp
        state = trajectory.State(X=xp.asarray(m.vertices, dtype=xp.float64))
        state.dt = step_size.initial_dt(cfg, solver, state.X, m.quality()["edge_mean"])
        self.integ = integ = schemes.integrator_class(cfg)(solver, state.dt, X0=m.vertices)
        state.cg_iterations = integ.iterations
        self.rate = cfg.chi
        for _ in range(WARM_STEPS):
            self._advance(state)
        self.state = state

    def _advance(self, state):
        F, geo = self.solver.forces(state.X)
        dt = self.integ.next_dt(state, geo)
        dX = self.integ.step(state, state.X, F, geo, dt, self.rate)
        state.X = state.X + dX
        state.step += 1
        state.t += dt
        return dX

    def time_step(self, N, dtype):
        self._advance(copy.copy(self.state))

    def peakmem_step(self, N, dtype):
        self._advance(copy.copy(self.state))

    def track_cg_iterations(self, N, dtype):
        self._advance(copy.copy(self.state))
        return self.integ.iterations[-1]

    track_cg_iterations.unit = "iterations"
