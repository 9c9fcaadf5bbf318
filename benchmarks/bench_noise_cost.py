"""What thermal noise costs a run: Stokes solves and wall time per step against the same run without noise (run by
hand, alone on the machine; the ratios are what to quote).

    python benchmarks/bench_noise_cost.py [--case wrinkling|equilibrium] [--repeat 2] [--out DIR] > numbers.md

Cases (float32 grids as the workflow's; the numbers differ from run to run only through the machine's load):

* ``wrinkling``: config/thermal.yaml's discretisation at S = 2224, Delta = 0.116 (N = 64, L = 5 R, the sharp coupling,
  a 2379-vertex quasi-uniform mesh, harmonic tension with the area ALE), 1 + 1 strain units, kT/kappa = 0.0405,
  noise seed 0;
* ``equilibrium``: a fixed-tension quasi-sphere (N = 32, 642 vertices at Delta = 0.04, tension_fixed 600, Lambda
  1e8, dt = 5e-4 tau, 0.5 tau; docs/history/thermal.md section 7's setup), float64.

Rows: the run without noise, then with noise for each setting of cg_precond (compliance: the rho_l diagonal; secant:
the BFGS model, tension_secant.py), noise_drift_every (1: the Ito drift's random finite difference every step; 0:
none) and cg_tol. Per step: steps, Stokes solves of the tension solves and the bending limit (the trajectory's
``stokes_solves``) and of the drift (``thermal_stokes_solves``), CG iterations (mean, max), and the wall time of the
run (median over ``--repeat`` runs) over the noiseless run's. Each noisy step also draws 3 N^3 normal deviates and
transforms one noise field (one FFT round trip), which the solve counts leave out.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import tempfile
from pathlib import Path

import xarray as xr

from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import legacy_config
from vesicle_core.model.units import chi_from_S
from vesicle_core.solver.simulate import run

CASES = {
    "wrinkling": dict(mesh=dict(n_vertices=2379, delta=0.116),
                      run=dict(chi=None, N=64, L=5.0, scheme="inextensible", coupling="sharp", tension_space="harmonic",
                               mesh_ale="area", dtype="float32", stretch=1.0, t_end=1.0, output_every=0.02)),
    "equilibrium": dict(mesh=dict(n_vertices=642, delta=0.04),
                        run=dict(chi=0.0, stretch=0.0, N=32, L=5.0, scheme="inextensible", tension_space="harmonic",
                                 tension_l_max=10, mesh_ale="area", tension_fixed=600.0, Lambda=1e8, dt=5e-4,
                                 t_end=0.5, output_every=0.01)),
}

SETTINGS = [  # (label, run overrides)
    ("no noise", dict(kT=0.0)),
    ("compliance, drift every step", dict(cg_precond="compliance", noise_drift_every=1)),
    ("secant, drift every step (the defaults)", dict(cg_precond="secant", noise_drift_every=1)),
    ("compliance, no drift", dict(cg_precond="compliance", noise_drift_every=0)),
    ("secant, no drift", dict(cg_precond="secant", noise_drift_every=0)),
    ("secant, no drift, cg_tol 1e-4", dict(cg_precond="secant", noise_drift_every=0, cg_tol=1e-4)),
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=sorted(CASES), default="wrinkling")
    ap.add_argument("--repeat", type=int, default=2, help="runs per setting (the wall time is their median)")
    ap.add_argument("--out", default=None, help="keep the runs here (default: a temporary directory)")
    a = ap.parse_args(argv)
    case = CASES[a.case]
    mesh = Mm.make_vesicle("quasiuniform", n_vertices=case["mesh"]["n_vertices"], target_delta=case["mesh"]["delta"])
    base = dict(case["run"], kT=0.0405, noise_seed=0)
    if base["chi"] is None:
        base["chi"] = chi_from_S(2224.0, case["mesh"]["delta"])  # the nominal Delta, as the workflow
    out = Path(a.out or tempfile.mkdtemp(prefix="noise_cost_"))
    print(f"case {a.case}: {mesh.vertices.shape[0]} vertices, " + ", ".join(f"{k} {v}" for k, v in base.items()))
    print()
    print("| run | steps | Stokes solves / step (tension + bending) | drift's solves / step | all / step "
          "| CG mean / max | wall [s] (median) | wall / step over no noise |")
    print("|---|---|---|---|---|---|---|---|")
    ref = None
    for label, over in SETTINGS:
        walls = []
        for k in range(a.repeat):
            d = out / f"{label.replace(' ', '_').replace(',', '')}_{k}"
            with xr.open_dataset(run(mesh, legacy_config(**{**base, **over}), d, progress=False)) as ds:
                at = dict(ds.attrs)
            walls.append(float(at["wall_time_s"]))
        steps = int(at["steps"])
        main_s, drift_s = at["stokes_solves"] / steps, at.get("thermal_stokes_solves", 0) / steps
        wall = statistics.median(walls)
        per_step = wall / steps
        ref = per_step if ref is None else ref
        print(f"| {label} | {steps} | {main_s:.2f} | {drift_s:.2f} | {main_s + drift_s:.2f} | "
              f"{at['cg_iterations_mean']:.2f} / {at['cg_iterations_max']} | {wall:.1f} | {per_step / ref:.2f} |")


if __name__ == "__main__":
    main()
