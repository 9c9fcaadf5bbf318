"""cutoff.exponent_vs_lmax: l_* (eq. 31) and the exponent of l_* ~ S^b against the PA's mode cutoff l_max."""

import numpy as np
import pytest

from vesicle_core.analysis import theory as T
from vesicle_core.errors import ConfigError
from vesicle_core.model.modes import default_l_max
from vesicle_core.validation.cutoff import DEFAULT_LMAX_LABEL, exponent_vs_lmax

DELTA = 0.116
S = [227.0, 553.0, 1106.5]
# 12 and 16 lie below the untruncated l_max_nontrivial at all three S (19, 27, 36), 40 above all of them
L_MAX = [12, 16, 40, None]


@pytest.fixture(scope="module")
def ds():
    return exponent_vs_lmax(DELTA, S, L_MAX)


@pytest.fixture(scope="module")
def reference():
    return {s: T.solve(DELTA, s) for s in S}


def test_layout(ds):
    assert dict(ds.sizes) == {"l_max": 4, "S": 3}
    assert ds["l_max"].values.tolist() == [12, 16, 40, DEFAULT_LMAX_LABEL]
    for name in ("l_star", "l_peak", "t_star", "l_max_nontrivial", "l_max_used", "truncated"):
        assert ds[name].dims == ("l_max", "S")
    for name in ("b", "b_low", "b_high", "prefactor", "n_truncated", "l_peak_b"):
        assert ds[name].dims == ("l_max",)
    assert ds["l_max_used"].sel(l_max=DEFAULT_LMAX_LABEL).values.tolist() == [default_l_max(s) for s in S]


def test_each_entry_is_the_projects_solve(ds):
    """Same seed, normalisation and thermal spectrum as theory.solve/sweep by default: identical numbers."""
    for L in (12, 40):
        for s in S:
            sol = T.solve(DELTA, s, l_max=L) if L == 40 else _quiet_solve(s, L)
            row = ds.sel(l_max=L, S=s)
            assert float(row.l_star) == sol.l_star and float(row.t_star) == sol.t_star
            assert int(row.l_max_nontrivial) == sol.l_max_nontrivial


def _quiet_solve(s, L):
    with pytest.warns(UserWarning, match="truncation"):
        return T.solve(DELTA, s, l_max=L)


def test_inactive_cutoff_equals_untruncated(reference):
    """A cutoff just above l_max_nontrivial only drops modes that hold < 1e-10 of the area at t_* and ~1e-5 at
    t = 0, so l_* and t_* agree with the untruncated solve far inside 1e-3 and the integers exactly."""
    cut = [reference[s].l_max_nontrivial + 2 for s in S]
    out = exponent_vs_lmax(DELTA, S, cut)
    for i, s in enumerate(S):
        row, ref = out.isel(l_max=i).sel(S=s), reference[s]
        assert not bool(row.truncated)
        assert float(row.l_star) == pytest.approx(ref.l_star, rel=1e-3)
        assert float(row.t_star) == pytest.approx(ref.t_star, rel=1e-3)
        assert float(row.l_peak) == ref.l_peak and int(row.l_max_nontrivial) == ref.l_max_nontrivial


def test_truncated_l_star_is_bounded_by_the_cutoff(ds, reference):
    """Eq. (31) is a weighted rms of l over 3 <= l <= l_max_nontrivial <= l_max."""
    used = ds["l_max_used"].values
    assert np.all(ds["l_max_nontrivial"].values <= used)
    assert np.all((ds["l_star"].values >= 3) & (ds["l_star"].values <= ds["l_max_nontrivial"].values))
    assert np.all(ds["l_peak"].values <= ds["l_max_nontrivial"].values)
    # the untruncated l_* at S = 1106.5 (16.8) exceeds 12 and 16: those cutoffs must be active and cap it
    assert reference[1106.5].l_star > 16
    for L in (12, 16):
        row = ds.sel(l_max=L, S=1106.5)
        assert bool(row.truncated) and int(row.l_max_nontrivial) == L and float(row.l_star) < L
    assert not ds["truncated"].sel(l_max=[40, DEFAULT_LMAX_LABEL]).values.any()
    assert ds["n_truncated"].values.tolist() == ds["truncated"].values.sum(axis=1).tolist()


def test_fit_is_least_squares_in_log_log(ds):
    for L in ds["l_max"].values:
        row = ds.sel(l_max=L)
        slope, intercept = np.polyfit(np.log(S), np.log(row.l_star.values), 1)
        assert float(row.b) == pytest.approx(slope, rel=1e-10)
        assert float(row.prefactor) == pytest.approx(np.exp(intercept), rel=1e-10)
        assert float(row.b_low) < float(row.b) < float(row.b_high)


def test_capping_flattens_the_power_law(ds):
    """With every S capped at l_max = 12 (l_* <= 12 against 8.4..16.8 untruncated) b must fall below the
    untruncated exponent; the active cutoff is the only difference between the two rows."""
    assert float(ds.b.sel(l_max=12)) < float(ds.b.sel(l_max=DEFAULT_LMAX_LABEL))


def test_solve_kwargs_are_passed_through():
    out = exponent_vs_lmax(DELTA, S, [None], normalisation="unit", seed=3)
    for s in S:
        ref = T.solve(DELTA, s, normalisation="unit", seed=3)
        row = out.sel(l_max=DEFAULT_LMAX_LABEL, S=s)
        assert float(row.l_star) == ref.l_star and int(row.l_max_used) == ref.l_max
    assert "unit" in out.attrs["solve_kwargs"]


@pytest.mark.parametrize(
    "args,kwargs,name",
    [
        ((0.0, S, [16]), {}, "delta"),
        ((DELTA, [227, 553], [16]), {}, "S_values"),
        ((DELTA, [227, -553, 1106.5], [16]), {}, r"S_values\[1\]"),
        ((DELTA, [227, 553, 553], [16]), {}, "S_values"),
        ((DELTA, [[227, 553, 1106.5]], [16]), {}, "S_values"),
        ((DELTA, S, [16, 2]), {}, r"l_max_values\[1\]"),
        ((DELTA, S, [16.5]), {}, r"l_max_values\[0\]"),
        ((DELTA, S, []), {}, "l_max_values"),
        ((DELTA, S, 16), {}, "l_max_values"),
        ((DELTA, S, [16, 16]), {}, "l_max_values"),
        ((DELTA, S, [16]), {"confidence": 1.0}, "confidence"),
        ((DELTA, S, [16]), {"l_max": 20}, "l_max"),
        ((DELTA, S, [16]), {"normalisaton": "unit"}, "normalisaton"),
        ((DELTA, S, [16]), {"normalisation": "sphere"}, "normalisation"),
    ],
)
def test_bad_input_names_the_argument(args, kwargs, name):
    with pytest.raises(ConfigError, match=name):
        exponent_vs_lmax(*args, **kwargs)


def test_truncation_warning_is_recorded_not_raised(recwarn):
    out = exponent_vs_lmax(DELTA, S, [12])
    assert out["truncated"].values.all()
    assert not [w for w in recwarn if "truncation" in str(w.message)]
