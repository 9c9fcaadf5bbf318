"""Which wrinkle pattern is this? A classifier on the morphology metrics, with thresholds set on synthetic fields.

Classes (generators: :mod:`.pattern_synth`): ripples, herringbone, labyrinth (wormlike), hexagons_up,
hexagons_down, peanut. The decision uses three metrics of :mod:`.morphology`, in this order:

1. **peanut** if the low-degree fraction (share of h^2 in l <= 6) exceeds ``low_degree``: the field is the lobes
   and waist of the whole vesicle, not wrinkles;
2. **ripples** if the crest alignment P >= ``ripples`` (all crests wind round one axis), **herringbone** if
   ``herringbone`` <= P < ``ripples`` (a common axis, crests at +-alpha to it: P ~ cos 2 alpha);
3. otherwise the crests have no common axis: **hexagons_up** / **hexagons_down** if the Euler-curve asymmetry
   A >= ``hexagons`` / <= -``hexagons`` (isolated bumps on a connected background, or its negative), else
   **labyrinth**.

P and |A| and the low-degree fraction are unchanged by h -> -h, and A changes sign exactly (the Euler
characteristic's duality), so flipping h swaps hexagons_up and hexagons_down and no other class.

Thresholds: :func:`calibrate` puts each one midway between the two classes it separates (between the largest value
of the lower class and the smallest of the upper class, both on synthetic samples drawn by
:func:`calibration_sample`). The defaults below came from ``calibrate(calibration_sample(n_per_cell=6,
seed=2026))``: 216 fields, each class on icosphere levels 4 and 5 (2562 and 10242 vertices), noise 0, 0.1 and 0.2,
k uniform in [10, 16], random orientation and phases; the margins (upper class's minimum minus lower class's
maximum) were 0.84 (low degree), 0.145 (ripples / herringbone), 0.129 (herringbone / labyrinth and hexagons) and
0.31 (|A|, hexagons / labyrinth). They were never fitted to a simulated vesicle.
Accuracy: docs/explanation/morphology.md and tests/analysis/test_pattern_class.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..geometry.surface import _as_mesh
from .crest_order import crest_alignment
from .excursion import euler_curve
from .morphology import (
    DEFAULT_LEVELS,
    Morphology,
    _vertex_field,
    characteristic_degree,
    ec_asymmetry,
    low_degree_fraction,
)
from .pattern_synth import CLASSES, sample

__all__ = ["Thresholds", "THRESHOLDS", "FEATURES", "features", "classify", "classify_features", "calibrate",
           "calibration_sample", "confusion"]

FEATURES = ("low_degree_fraction", "crest_alignment", "ec_asymmetry")


@dataclass(frozen=True)
class Thresholds:
    """Decision thresholds of the classifier (module docstring)."""

    low_degree: float = 0.541
    ripples: float = 0.821
    herringbone: float = 0.383
    hexagons: float = 0.355


THRESHOLDS = Thresholds()


def features(vertices, faces, h) -> dict:
    """The classifier's inputs (FEATURES) of the field h (per vertex or per triangle), plus l_c."""
    v, f = _as_mesh(vertices, faces)
    x, _ = _vertex_field(v, f, h)
    chi = euler_curve(f, x, DEFAULT_LEVELS)
    return {"low_degree_fraction": low_degree_fraction(v, f, x), "crest_alignment": crest_alignment(v, f, x)[0],
            "ec_asymmetry": ec_asymmetry(DEFAULT_LEVELS, chi), "l_c": characteristic_degree(v, f, x)[0]}


def classify_features(feat, thresholds: Thresholds = THRESHOLDS) -> str:
    """The class of a field from its :func:`features` (or a :class:`~.morphology.Morphology`)."""
    if isinstance(feat, Morphology):
        feat = {k: getattr(feat, k) for k in FEATURES}
    missing = [k for k in FEATURES if k not in feat]
    if missing:
        raise ConfigError(f"features lack {missing}; they need {list(FEATURES)}")
    t = thresholds
    if feat["low_degree_fraction"] > t.low_degree:
        return "peanut"
    if feat["crest_alignment"] >= t.ripples:
        return "ripples"
    if feat["crest_alignment"] >= t.herringbone:
        return "herringbone"
    if feat["ec_asymmetry"] >= t.hexagons:
        return "hexagons_up"
    if feat["ec_asymmetry"] <= -t.hexagons:
        return "hexagons_down"
    return "labyrinth"


def classify(vertices, faces, h, thresholds: Thresholds = THRESHOLDS) -> str:
    """Class of the height field ``h`` about the fitted ellipsoid on the closed surface (vertices, faces)."""
    return classify_features(features(vertices, faces, h), thresholds)


def calibration_sample(meshes, n_per_cell=6, seed=2026, noises=(0.0, 0.1, 0.2)) -> dict:
    """{class: {feature: array}} over ``n_per_cell`` random fields per (class, mesh, noise); meshes: a list of
    (unit-sphere vertices, faces)."""
    rng = np.random.default_rng(seed)
    out = {c: {k: [] for k in FEATURES} for c in CLASSES}
    for c in CLASSES:
        for v, f in meshes:
            for noise in noises:
                for _ in range(int(n_per_cell)):
                    feat = features(v, f, sample(c, v, rng, noise=noise))
                    for k in FEATURES:
                        out[c][k].append(feat[k])
    return {c: {k: np.asarray(x) for k, x in d.items()} for c, d in out.items()}


def _midway(lower, upper):
    lo, hi = float(np.max(lower)), float(np.min(upper))
    return 0.5 * (lo + hi), hi - lo


def calibrate(table) -> tuple[Thresholds, dict]:
    """Thresholds midway between the classes each one separates, and the margins (upper class's minimum minus
    lower class's maximum; negative: the classes overlap on the sample)."""
    non_peanut = [c for c in CLASSES if c != "peanut"]
    cat = {k: np.concatenate([table[c][k] for c in non_peanut]) for k in FEATURES}
    low, m_low = _midway(cat["low_degree_fraction"], table["peanut"]["low_degree_fraction"])
    rip, m_rip = _midway(table["herringbone"]["crest_alignment"], table["ripples"]["crest_alignment"])
    iso = np.concatenate([table[c]["crest_alignment"] for c in ("labyrinth", "hexagons_up", "hexagons_down")])
    her, m_her = _midway(iso, table["herringbone"]["crest_alignment"])
    hx, m_hx = _midway(np.abs(table["labyrinth"]["ec_asymmetry"]),
                       np.abs(np.concatenate([table["hexagons_up"]["ec_asymmetry"],
                                              table["hexagons_down"]["ec_asymmetry"]])))
    return (Thresholds(low_degree=low, ripples=rip, herringbone=her, hexagons=hx),
            {"low_degree": m_low, "ripples": m_rip, "herringbone": m_her, "hexagons": m_hx})


def confusion(meshes, n_per_cell, seed, noises=(0.0, 0.1, 0.2), thresholds: Thresholds = THRESHOLDS, flip=False):
    """Confusion counts {true class: {predicted class: n}} over ``n_per_cell`` fresh synthetic fields per (class,
    mesh, noise). flip: classify -h and count it under the class -h belongs to (up and down hexagons swapped)."""
    swap = {"hexagons_up": "hexagons_down", "hexagons_down": "hexagons_up"}
    rng = np.random.default_rng(seed)
    out = {c: dict.fromkeys(CLASSES, 0) for c in CLASSES}
    for c in CLASSES:
        for v, f in meshes:
            for noise in noises:
                for _ in range(int(n_per_cell)):
                    h = sample(c, v, rng, noise=noise)
                    truth = swap.get(c, c) if flip else c
                    out[truth][classify(v, f, -h if flip else h, thresholds)] += 1
    return out
