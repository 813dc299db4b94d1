"""TemplateBank: HDF5 round trip, selection, default bank cache; template plots."""

import h5py
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from spiralbayes.templates import (
    TemplateBank,
    compromise_bank,
    default_bank,
    make_template,
    variant_bank,
)
from spiralbayes.templates import bank as bank_mod
from spiralbayes.templates import wake as wake_mod

TINY = dict(n_x=24, n_phi=90, n_eta=256)

@pytest.fixture(scope="module")
def small_bank():
    ts = [make_template(m, tau, b, h, store_brightness=False, **TINY)
          for m in (0.3, 1.0) for tau in (0.1, 3.0) for b in (0.0, 10.0) for h in "RL"]
    return TemplateBank(ts, {"note": "test"})


def test_bank_roundtrip(tmp_path, small_bank):
    path = small_bank.save(tmp_path / "bank.h5")
    assert [p.name for p in tmp_path.iterdir()] == ["bank.h5"]  # no temporary left behind
    with h5py.File(path) as f:
        assert f.attrs["format_version"] >= 1
        assert f["templates"][small_bank.names[0]]["delta"].dtype == np.float32
    back = TemplateBank.load(path)
    assert back.names == small_bank.names
    for a, b in zip(small_bank, back):
        np.testing.assert_array_equal(a.delta, b.delta)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.phi, b.phi)
        assert a.parameters == b.parameters
        assert b.provenance["settings"]["n_x"] == 24
    assert back.provenance["note"] == "test"


def test_single_template_save_load(tmp_path):
    t = make_template(1.0, 1.0, 10.0, "L", **TINY)
    p = TemplateBank([t]).save(tmp_path / "one.h5")
    u = TemplateBank.load(p)[t.name]
    assert u.name == t.name and u.hand == "L" and u.beta == 10.0
    np.testing.assert_array_equal(u.delta, t.delta)


def test_select_and_index(small_bank):
    assert len(small_bank) == 16
    sub = small_bank.select(mass=1.0, tau0=[0.1, 3.0], beta=10, hand="r")
    assert len(sub) == 2
    assert all(t.mass == 1.0 and t.beta == 10 and t.hand == "R" for t in sub)
    assert len(small_bank.select(hand=["R", "L"])) == 16
    assert len(small_bank.select(mass=0.1)) == 0
    t = small_bank.get(0.3, 3.0, 0.0, "L")
    assert small_bank[t.name] is t and t.name in small_bank
    assert small_bank[3] is list(small_bank)[3]
    params = small_bank.parameters
    assert params.shape == (16,) and set(params["hand"]) == {"R", "L"}
    with pytest.raises(KeyError, match="no template named"):
        small_bank["nope"]
    with pytest.raises(LookupError):
        small_bank.get(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="unknown hand"):
        small_bank.select(hand="X")


def test_duplicate_names_rejected(small_bank):
    with pytest.raises(ValueError, match="unique"):
        TemplateBank([small_bank[0], small_bank[0]])


def test_load_rejects_other_files(tmp_path):
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["x"] = 1
    with pytest.raises(ValueError, match="not a spiralbayes template bank"):
        TemplateBank.load(p)
    with pytest.raises(FileNotFoundError):
        TemplateBank.load(tmp_path / "missing.h5")


def test_compromise_bank_builds_once_and_caches(tmp_path, monkeypatch):
    bank = compromise_bank(cache_dir=tmp_path, **TINY)
    assert len(bank) == 192  # the paper's 64 for each H/r in {0.05, 0.07, 0.10}
    for h in (0.05, 0.07, 0.10):
        sub = bank.select(h_p=h)
        assert len(sub) == 64 and all(t.h_p == h for t in sub)
        assert all(f"_h{h:.2f}_" in t.name for t in sub)
    assert bank.get(1.0, 3.0, 10.0, "L", h_p=0.05).name == "wake_m1_tau3_b10_h0.05_L"
    with pytest.raises(LookupError, match="3 templates match"):
        bank.get(1.0, 3.0, 10.0, "L")
    files = list(tmp_path.glob("bank-*.h5"))
    assert len(files) == 1

    def boom(*a, **k):
        raise AssertionError("rebuilt although cached")

    monkeypatch.setattr(bank_mod, "paper_grid", boom)
    again = compromise_bank(cache_dir=tmp_path, **TINY)
    assert again.names == bank.names
    np.testing.assert_array_equal(again[5].delta, bank[5].delta)
    monkeypatch.undo()
    # a changed generator setting or set of aspect ratios gets its own cache file
    compromise_bank(cache_dir=tmp_path, h_ps=(0.07,), **{**TINY, "n_phi": 180})
    assert len(list(tmp_path.glob("bank-*.h5"))) == 2
    assert len(compromise_bank(cache_dir=tmp_path, h_ps=(0.07,), **{**TINY, "n_phi": 180})) == 64
    assert len(list(tmp_path.glob("bank-*.h5"))) == 2


def test_default_bank_is_the_morphology_robust_bank_and_caches(tmp_path, monkeypatch):
    """The default bank is the variant bank: the paper's grid in three morphologies per H/r, each
    variant's templates distinct from the compromise's, built once and then read from the cache."""
    from spiralbayes.templates import variants as variants_mod

    bank = default_bank(cache_dir=tmp_path, h_p=0.07, **TINY)
    assert len(bank) == 3 * 64
    assert bank.names == variant_bank(h_ps=(0.07,), cache_dir=tmp_path, **TINY).names
    by_variant = {}
    for t in bank:
        by_variant.setdefault(t.provenance["variant"], []).append(t)
    assert sorted(by_variant) == ["compromise", "hydro", "wakeflow"]
    assert all(len(ts) == 64 for ts in by_variant.values())
    hydro = bank["hydro_m1_tau3_b10_h0.07_R"]
    plain = bank["wake_m1_tau3_b10_h0.07_R"]
    assert not np.allclose(hydro.delta, plain.delta)  # a different shape, not a relabelled copy
    # the compromise variant of the robust bank is the single-morphology bank's template
    single = compromise_bank(cache_dir=tmp_path, h_ps=(0.07,), **TINY)
    np.testing.assert_allclose(plain.delta, single["wake_m1_tau3_b10_h0.07_R"].delta, rtol=0, atol=1e-6)
    assert len(single) == 64 and len(list(tmp_path.glob("variants-*.h5"))) == 1

    def boom(*a, **k):
        raise AssertionError("rebuilt although cached")

    monkeypatch.setattr(variants_mod, "variant_grid", boom)
    assert default_bank(cache_dir=tmp_path, h_p=0.07, **TINY).names == bank.names


def test_default_cache_dir_env(monkeypatch, tmp_path):
    monkeypatch.setenv("SPIRALBAYES_CACHE", str(tmp_path / "sb"))
    assert bank_mod.default_cache_dir() == tmp_path / "sb"
    monkeypatch.delenv("SPIRALBAYES_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert bank_mod.default_cache_dir() == tmp_path / "xdg" / "spiralbayes"


def test_corrupt_cache_is_rebuilt(tmp_path):
    key = wake_mod.WakeSettings(**TINY).key()
    (tmp_path / f"bank-{key}.h5").write_bytes(b"not hdf5")
    bank = compromise_bank(cache_dir=tmp_path, h_ps=(0.07,), **TINY)
    assert len(bank) == 64
    assert TemplateBank.load(tmp_path / f"bank-{key}.h5").names == bank.names


def test_aspect_ratio_is_carried_by_names_metadata_and_mirror_matching(tmp_path):
    from spiralbayes.inference.detection.verdict import mirror_index
    from spiralbayes.templates.template import template_metadata

    ts = [make_template(1.0, 3.0, 10.0, hand, h_p=h, store_brightness=False, **TINY)
          for h in (0.05, 0.10) for hand in "RL"]
    bank = TemplateBank.load(TemplateBank(ts).save(tmp_path / "b.h5"))
    assert bank.names == ["wake_m1_tau3_b10_h0.05_R", "wake_m1_tau3_b10_h0.05_L",
                          "wake_m1_tau3_b10_h0.10_R", "wake_m1_tau3_b10_h0.10_L"]
    assert [t.h_p for t in bank] == [0.05, 0.05, 0.10, 0.10]
    assert bank[2].mirror().name == bank[3].name
    meta = [template_metadata(t) for t in bank]
    assert [m["h_p"] for m in meta] == [0.05, 0.05, 0.10, 0.10]
    # each template's mirror is the other hand at the same H/r, not the same hand elsewhere
    from types import SimpleNamespace

    result = SimpleNamespace(templates=meta)
    assert [mirror_index(result, i) for i in range(4)] == [1, 0, 3, 2]
    assert len(bank.select(h_p=[0.05, 0.07])) == 2 and len(bank.select(h_p=0.07)) == 0
