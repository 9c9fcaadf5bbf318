"""Resolution of the IBM membrane: single-mode relaxation rates against linear theory, per grid, kernel and coupling.

For each kernel (3-point, 4-point, 6-point), coupling (``kernel``: the paper's; ``sharp``: window deconvolution with
floor f), mesh edge (2h, the kernel's rule; h, the sharp coupling's) and grid N, the relaxation rate of
r = 1 + eps Y_l0 (vesicle_core.validation.relaxation) over the clean-interface theory, l = 2 corrected for the
periodic box, and
l_res: the highest l whose ratio stays within 5% of 1 for every l up to it. Per kernel and coupling also the
regularised Stokeslet (vesicle_core.validation.stokeslet): hydrodynamic radius, translation invariance of the self and
pair
mobility over sub-grid shifts, and the pair mobility against the periodic Oseen / RPY tensors at 2-10 h.

    python benchmarks/bench_resolution.py [--Ns 64 96 128 192] [--kernels peskin4] [--couplings kernel sharp:0.01]
        [--edges 1 2] [--inextensible [--tension-space harmonic] [--cg-tol 1e-6]] [--json out.json]

``sharp:F`` is the sharp coupling with floor F; ``sharp`` alone takes the parameter's default. Cost on 2 cores: one
Stokes solve per (N, l) (clean interface) plus the meshes (a 21,000-vertex quasi-uniform mesh, edge h at N = 192,
takes ~1 min once); the inextensible rates need a tension CG each (tens to hundreds of solves).
"""

from __future__ import annotations

import argparse
import json
import time

from vesicle_core.model.parameters import SHARP_FLOOR
from vesicle_core.validation.relaxation import resolution_table
from vesicle_core.validation.stokeslet import fmt_report, stokeslet_report

LS = (2, 3, 4, 6, 8, 10, 13, 16, 20, 25, 30, 40)


def parse_coupling(text):
    """'kernel', 'sharp' or 'sharp:0.01' -> (coupling, floor or None)."""
    name, _, floor = text.partition(":")
    if name not in ("kernel", "sharp"):
        raise SystemExit(f"--couplings: expected kernel, sharp or sharp:FLOOR, got {text!r}")
    return name, (float(floor) if floor else (SHARP_FLOOR if name == "sharp" else None))


def main(Ns, kernels, couplings, edges, membrane="clean", tol=0.05, stokeslet=True, cg_tol=1e-9,
         tension_space="triangle", eps=1e-3):
    out = []
    for kernel in kernels:
        for coupling, floor in couplings:
            if stokeslet:
                print(fmt_report(stokeslet_report(kernel, coupling, floor or SHARP_FLOOR)), flush=True)
            for edge in edges:
                t0 = time.perf_counter()
                tab = resolution_table(Ns, LS, membrane=membrane, tol=tol, kernel=kernel, coupling=coupling,
                                       sharp_floor=floor, edge=edge, box_correct=True, cg_tol=cg_tol,
                                       tension_space=tension_space, eps=eps,
                                       progress=lambda s: print("   ", s, flush=True))
                for N, row in tab.items():
                    out.append({"kernel": kernel, "coupling": coupling, "floor": floor, "edge_h": edge, "N": N,
                                "membrane": membrane, **row})
                tag = f"{kernel} {coupling}" + (f" {floor:g}" if floor else "")
                print(f"  {tag}, edge {edge:g}h: " + ", ".join(f"N={N} l_res {r['l_res']}" for N, r in tab.items())
                      + f" ({time.perf_counter() - t0:.0f} s)", flush=True)
    return out


def markdown(rows):
    """One row per (kernel, coupling, edge, N): the ratios and l_res."""
    head = "| kernel | coupling | edge | N | vertices | l_res | " + " | ".join(f"l = {l}" for l in LS) + " |"
    lines = [head, "|" + "---|" * (6 + len(LS))]
    for r in rows:
        cpl = r["coupling"] + (f" {r['floor']:g}" if r["floor"] else "")
        cells = [f"{r['ratios'][l]:.3f}" if l in r["ratios"] else "" for l in LS]
        lines.append(f"| {r['kernel']} | {cpl} | {r['edge_h']:g}h | {r['N']} | {r['n_vertices']} | {r['l_res']} | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--Ns", type=int, nargs="+", default=[64, 96, 128, 192])
    ap.add_argument("--kernels", nargs="+", default=["roma3", "peskin4", "bao6"])
    ap.add_argument("--couplings", nargs="+", default=["kernel", "sharp"])
    ap.add_argument("--edges", type=float, nargs="+", default=[1.0, 2.0], help="mesh edge in h")
    ap.add_argument("--inextensible", action="store_true", help="vesicle rates Gamma_l (tension solve) instead")
    ap.add_argument("--no-stokeslet", action="store_true", help="skip the regularised-Stokeslet properties")
    ap.add_argument("--cg-tol", type=float, default=1e-9,
                    help="inextensible: tension CG tolerance (1e-6 is ample: the start residual is ~3e-3)")
    ap.add_argument("--eps", type=float, default=1e-3,
                    help="mode amplitude (1e-4 keeps the inextensible rates of l >~ 15 linear)")
    ap.add_argument("--tension-space", default="triangle", choices=("triangle", "harmonic"),
                    help="inextensible: the tension space (run parameter tension_space)")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args()
    rows = main(a.Ns, a.kernels, [parse_coupling(c) for c in a.couplings], a.edges,
                "inextensible" if a.inextensible else "clean", stokeslet=not a.no_stokeslet, cg_tol=a.cg_tol,
                tension_space=a.tension_space, eps=a.eps)
    print(markdown(rows))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1)
