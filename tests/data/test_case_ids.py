"""Case ids (data/case_ids.py): readable, parsed back, stable under float noise, bad input named."""

import pytest

from vesicle_core.data import case_ids as Ci
from vesicle_core.errors import ConfigError
from vesicle_core.model.units import chi_from_S


@pytest.mark.parametrize("kwargs, expect", [
    (dict(delta=0.116, S=553, N=64, family="icosphere", level=4), "D0.116_S553_N64_L4"),
    (dict(delta=0.116, S=1106.5, N=32, family="icosphere", level=3), "D0.116_S1106.5_N32_L3"),
    (dict(delta=0.997, chi=83.5, N=512, family="quasiuniform", n_vertices=26070), "D0.997_chi83.5_N512_Q26070"),
    (dict(delta=0.116, S=553, N=16, family="icosphere", level=2, tag="fine-dt"), "D0.116_S553_N16_L2_fine-dt"),
    (dict(delta=0.116, S=553, N=128, family="quasiuniform", n_vertices=2562, kT=0.0405, noise_seed=7),
     "D0.116_S553_N128_Q2562_kT0.0405_n7"),
    (dict(delta=0.116, S=553, N=16, family="icosphere", level=2, kT=0.405, noise_seed=0, tag="hot"),
     "D0.116_S553_N16_L2_kT0.405_n0_hot"),
])
def test_case_ids_are_readable_and_parse_back(kwargs, expect):
    cid = Ci.case_id(**kwargs)
    assert cid == expect
    p = Ci.parse_case_id(cid)
    assert p["Delta"] == kwargs["delta"] and p["N"] == kwargs["N"]
    if "S" in kwargs:
        assert p["S"] == kwargs["S"] and p["chi"] == pytest.approx(chi_from_S(kwargs["S"], kwargs["delta"]))
    else:
        assert p["chi"] == kwargs["chi"] and p["S"] > 0
    # an ensemble member carries kT and its noise seed; a deterministic case neither (kT = 0 keeps the old ids)
    assert p["kT"] == kwargs.get("kT") and p["noise_seed"] == kwargs.get("noise_seed")
    assert p["tag"] == kwargs.get("tag")
    if "kT" not in kwargs:
        assert Ci.case_id(**kwargs, kT=0.0, noise_seed=5) == expect


def test_ids_do_not_depend_on_float_noise_and_reject_bad_input():
    assert Ci.case_id(0.116, S=553.0000000001, N=32, family="icosphere", level=3) == "D0.116_S553_N32_L3"
    assert Ci.theory_id(0.116, 2224.0) == "D0.116_S2224"
    assert Ci.mesh_id(0.116, "icosphere", 3) == "icosphere_L3_D0.116"
    assert Ci.mesh_id(0.997, "quasiuniform", 5, 26070, 0) == "quasiuniform_n26070_s0_D0.997"
    assert Ci.parse_case_id("icosphere_L3_D0.116") is None
    assert Ci.parse_case_id("D0.116_S553")["N"] is None
    with pytest.raises(ConfigError):
        Ci.case_id(0.116, S=1, chi=1)
    with pytest.raises(ConfigError, match="tag"):
        Ci.case_id(0.116, S=1, tag="bad tag")
