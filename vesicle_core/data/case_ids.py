"""Readable identifiers of sweep points, built from their physical parameters only.


Identifiers
-----------
Sweep points get readable ids built from their physical parameters only (the Snakemake workflow and this
module share the builders below, so a path always tells what is in it):

    case      D0.116_S553_N32_L3        Delta, S (or ``chi67`` when the flow was given as chi), grid N, mesh
              D0.116_S553_N512_Q26070   (L<level>: icosphere; Q<n_vertices>[s<seed>]: quasi-uniform family),
              D0.116_S553_N32_L3_fine   optional tag (letters, digits, '-') for otherwise equal cases
              D0.116_S553_N128_Q2562_kT0.0405_n3
                                        thermal noise on (kT > 0): k_B T / kappa and the noise seed (one
                                        member of an ensemble; kT = 0 writes neither, as before)
    theory    D0.116_S553               the perturbation analysis depends on Delta and S only
    mesh      icosphere_L3_D0.116, quasiuniform_n26070_s0_D0.997

Numbers are written with ``%.6g`` (``1106.5``, ``0.116``); ``parse_case_id`` reads every form back. The ids hold
the *nominal* (configured) Delta and S; the datasets themselves record the meshed Delta, which differs from it by
~1e-13 when the mesh was built with ``--delta``.

The catalog (:mod:`vesicle_core.data.catalog`) and the Snakemake workflow share these builders.
"""

from __future__ import annotations

import math
import re

from ..errors import ConfigError
from ..model.parameters import MESH_PARAMETERS, RUN_PARAMETERS
from ..model.parameters import defaults as parameter_defaults

__all__ = ["TAG_PATTERN", "case_id", "fmt_number", "mesh_id", "parse_case_id", "theory_id"]

TAG_PATTERN = r"[A-Za-z0-9][A-Za-z0-9-]*"


# --------------------------------------------------------------------------- identifiers
def fmt_number(x) -> str:
    """Compact, stable text of a number for ids: %.6g without '+' in exponents (553, 1106.5, 0.116, 1e-05)."""
    x = float(x)
    if not math.isfinite(x):
        raise ConfigError(f"cannot build an id from the number {x!r}")
    if x == int(x) and abs(x) < 1e15:
        x = int(x)
        return str(x) if abs(x) < 1e6 else f"{x:.6g}".replace("e+", "e")
    return f"{x:.6g}".replace("e+", "e")


# the id functions default to the parameter table's mesh and grid (one home for defaults)
_MESH_DEFAULTS = parameter_defaults(MESH_PARAMETERS)
_RUN_DEFAULT_N = parameter_defaults(RUN_PARAMETERS)["N"]


def _mesh_part(family, level, n_vertices=None, seed=0):
    if family == "icosphere":
        return f"L{int(level)}"
    if family == "quasiuniform":
        part = f"Q{int(n_vertices)}" if n_vertices else f"QL{int(level)}"
        return part + (f"s{int(seed)}" if seed else "")
    raise ConfigError(f"mesh family must be 'icosphere' or 'quasiuniform', got {family!r}")


def case_id(delta, S=None, chi=None, N=_RUN_DEFAULT_N, family=_MESH_DEFAULTS["family"], level=_MESH_DEFAULTS["level"],
            n_vertices=None, seed=0, tag=None, kT=0.0, noise_seed=0) -> str:
    """Id of one simulation case from its physical parameters (module docstring)."""
    if (S is None) == (chi is None):
        raise ConfigError("a case needs exactly one of S and chi")
    flow = f"S{fmt_number(S)}" if S is not None else f"chi{fmt_number(chi)}"
    out = f"D{fmt_number(delta)}_{flow}_N{int(N)}_{_mesh_part(family, level, n_vertices, seed)}"
    if kT is not None and float(kT) > 0:
        out += f"_kT{fmt_number(kT)}_n{int(noise_seed)}"
    if tag:
        if not re.fullmatch(TAG_PATTERN, str(tag)):
            raise ConfigError(f"tag must match {TAG_PATTERN} (letters, digits, '-'), got {tag!r}")
        out += f"_{tag}"
    return out


def theory_id(delta, S, seed=0) -> str:
    """Id of a perturbation-analysis dataset: it depends on Delta, S (and the thermal seed) only."""
    return f"D{fmt_number(delta)}_S{fmt_number(S)}" + (f"_seed{int(seed)}" if seed else "")


def mesh_id(delta, family=_MESH_DEFAULTS["family"], level=_MESH_DEFAULTS["level"], n_vertices=None, seed=0,
            radius=1.0) -> str:
    """Id of a mesh: family, resolution, seed and target Delta (meshes are shared between flow strengths)."""
    if family == "icosphere":
        base = f"icosphere_L{int(level)}"
    elif family == "quasiuniform":
        nv = int(n_vertices) if n_vertices else 10 * 4 ** int(level) + 2
        base = f"quasiuniform_n{nv}_s{int(seed)}"
    else:
        raise ConfigError(f"mesh family must be 'icosphere' or 'quasiuniform', got {family!r}")
    out = f"{base}_D{fmt_number(delta)}"
    if float(radius) != 1.0:
        out += f"_R{fmt_number(radius)}"
    return out


_NUM = r"[0-9]+(?:\.[0-9]*)?(?:e-?[0-9]+)?"
_CASE_RE = re.compile(
    rf"^D(?P<delta>{_NUM})_(?:S(?P<S>{_NUM})|chi(?P<chi>{_NUM}))"
    rf"(?:_N(?P<N>[0-9]+)_(?:L(?P<level>[0-9]+)|QL(?P<qlevel>[0-9]+)(?:s(?P<qseed>[0-9]+))?"
    rf"|Q(?P<nv>[0-9]+)(?:s(?P<seed>[0-9]+))?))?"
    rf"(?:_kT(?P<kT>{_NUM})_n(?P<noise_seed>[0-9]+))?"
    rf"(?:_seed(?P<theory_seed>[0-9]+))?(?:_(?P<tag>{TAG_PATTERN}))?$"
)


def parse_case_id(text: str) -> dict | None:
    """Parameters encoded in a case or theory id (None if ``text`` is not such an id).

    Returns Delta, S, chi (both filled: the missing one from :mod:`units`), N, mesh_family, mesh_level,
    n_vertices, kT, noise_seed, tag; entries not encoded are None (kT and noise_seed: a deterministic case).
    """
    from ..model.units import S_from_chi, chi_from_S

    m = _CASE_RE.match(str(text))
    if not m:
        return None
    g = m.groupdict()
    delta = float(g["delta"])
    if delta <= 0:
        return None
    S = float(g["S"]) if g["S"] is not None else None
    chi = float(g["chi"]) if g["chi"] is not None else None
    if S is None:
        S = S_from_chi(chi, delta)
    else:
        chi = chi_from_S(S, delta)
    out = {"Delta": delta, "S": S, "chi": chi, "N": None, "mesh_family": None, "mesh_level": None,
           "n_vertices": None, "kT": float(g["kT"]) if g["kT"] is not None else None,
           "noise_seed": int(g["noise_seed"]) if g["noise_seed"] is not None else None, "tag": g["tag"]}
    if g["N"] is not None:
        out["N"] = int(g["N"])
        if g["level"] is not None:
            out.update(mesh_family="icosphere", mesh_level=int(g["level"]))
        elif g["qlevel"] is not None:
            out.update(mesh_family="quasiuniform", mesh_level=int(g["qlevel"]))
        else:
            out.update(mesh_family="quasiuniform", n_vertices=int(g["nv"]))
    return out


