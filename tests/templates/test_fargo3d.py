"""FARGO3D reader on small outputs written in FARGO3D's binary layout."""

import numpy as np
import pytest

from spiralbayes.templates import TemplateBank, read_fargo3d
from spiralbayes.templates.fargo3d import read_field, read_planet, read_variables

NX, NY, NGH = 96, 30, 3
PHI_P = 1.0  # planet azimuth in the run's frame [rad] (not on a cell centre)
BUMP_DPHI, BUMP_R = 0.5, 1.3  # density bump relative to the planet
H0 = 0.07


def _edges():
    phi_e = np.linspace(-np.pi, np.pi, NX + 1)
    r_all = np.geomspace(0.4, 2.5, NY + 1 + 2 * NGH)  # 3 ghost edges at each end
    return phi_e, r_all


def _density(n, scale=0.01):
    phi_e, r_all = _edges()
    r_e = r_all[NGH: NGH + NY + 1]
    r = 0.5 * (r_e[1:] + r_e[:-1])[:, None]
    phi = 0.5 * (phi_e[1:] + phi_e[:-1])[None, :]
    sigma = scale / r * np.ones_like(phi)
    if n > 0:
        dphi = (phi - PHI_P - BUMP_DPHI + np.pi) % (2 * np.pi) - np.pi
        sigma = sigma * (1 + 0.5 * np.exp(-((r - BUMP_R) / 0.08) ** 2 - (dphi / 0.15) ** 2))
    return sigma


def _write_field(d, name, n, arr, ncpu=None, blocks=None):
    if ncpu is None:
        arr.astype("<f8").tofile(d / f"{name}{n}.dat")
        return
    if blocks is None:  # FARGO3D's round-robin split of NY over ncpu
        rest, base = NY % ncpu, NY // ncpu
        sizes = [base + 1 if k < rest else base for k in range(ncpu)]
        y0 = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        blocks = list(zip(y0, sizes))
    for rank, (y0, ny) in enumerate(blocks):
        arr[y0: y0 + ny].astype("<f8").tofile(d / f"{name}{n}_{rank}.dat")


def write_run(d, *, ncpu=None, blocks=None, grid_inf=False, fluid="dust1", fork_names=False,
              energy=None, planet_mass=3.0 * H0**3):
    d.mkdir(parents=True, exist_ok=True)
    (d / "variables.par").write_text(
        f"NX\t{NX}\nNY\t{NY}\nNZ\t1\nASPECTRATIO\t{H0}\nFLARINGINDEX\t0.25\nSIGMA0\t1.0\n"
        "SIGMASLOPE\t1.0\nDUST_TO_GAS\t0.01\nR0\t1.0\nSPACING\tLog\nFRAME\tC\n"
    )
    phi_e, r_all = _edges()
    np.savetxt(d / "domain_x.dat", phi_e)
    np.savetxt(d / "domain_y.dat", r_all)
    rows = [[n, np.cos(PHI_P), np.sin(PHI_P), 0, -np.sin(PHI_P), np.cos(PHI_P), 0, planet_mass, n * 6.28, 1.0]
            for n in (0, 5)]
    np.savetxt(d / "planet0.dat", rows)
    if grid_inf:
        for rank, (y0, ny) in enumerate(blocks):
            (d / f"grid{rank:03d}.inf").write_text(
                f"CPU_Rank\tY0\tYN\tZ0\tZN\tIndexY\tIndexZ\n{rank}\t{y0}\t{y0 + ny - 1}\t0\t0\t{rank}\t0\n"
            )
    for n in (0, 5):
        name = "dustdens1_" if fork_names else f"{fluid}dens"
        _write_field(d, name, n, _density(n), ncpu, blocks)
        if energy is not None:
            _write_field(d, "gasenergy", n, energy(n), ncpu, blocks)
            _write_field(d, "gasdens", n, _density(n, 1.0), ncpu, blocks)
    return d


def _peak(t):
    i, j = np.unravel_index(np.argmax(t.delta), t.delta.shape)
    return t.x[i], (t.phi[j] + np.pi) % (2 * np.pi) - np.pi


def test_merged_output_planet_at_phi_zero(tmp_path):
    run = write_run(tmp_path / "merged")
    t = read_fargo3d(run, 5, tau0=0.3, x_range=None)
    _, r_all = _edges()
    r_e = r_all[NGH: NGH + NY + 1]
    np.testing.assert_allclose(t.x, 0.5 * (r_e[1:] + r_e[:-1]))  # ghosts dropped, r_p = 1
    assert t.delta.shape == (NY, NX)
    x_pk, phi_pk = _peak(t)
    dphi = 2 * np.pi / NX
    assert abs(phi_pk - BUMP_DPHI) <= dphi  # the bump sits 0.5 rad ahead of the planet
    assert abs(np.log(x_pk / BUMP_R)) <= np.log(r_all[1] / r_all[0])
    assert t.mass == pytest.approx(3.0)
    assert t.h_p == pytest.approx(H0) and t.hand == "R"
    # the run's folder and τ0 in the name: two runs' maps at two depths fit in one bank
    other = read_fargo3d(write_run(tmp_path / "other"), 5, tau0=3.0)
    names = [m.name for m in (t, t.mirror(), other, other.mirror())]
    assert names == ["fargo3d_merged_dust1_5_tau0.3_R", "fargo3d_merged_dust1_5_tau0.3_L",
                     "fargo3d_other_dust1_5_tau3_R", "fargo3d_other_dust1_5_tau3_L"]
    assert len(TemplateBank([t, t.mirror(), other, other.mirror()])) == 4
    assert t.provenance["sigma_ref"] == pytest.approx(0.01, rel=1e-3)  # from output 0 at r_p
    # far from the bump the map is flat
    far = np.abs(np.log(t.x / BUMP_R)) > 0.5
    assert np.max(np.abs(t.delta[far])) < 1e-6


def test_per_rank_outputs_match_merged(tmp_path):
    merged = read_fargo3d(write_run(tmp_path / "m"), 5, tau0=1.0)
    rr = read_fargo3d(write_run(tmp_path / "r", ncpu=4), 5, tau0=1.0)  # 8, 8, 7, 7 rows
    np.testing.assert_array_equal(rr.delta, merged.delta)
    blocks = [(0, 10), (10, 20)]  # an uneven split described by grid*.inf
    gi = read_fargo3d(write_run(tmp_path / "g", ncpu=2, blocks=blocks, grid_inf=True), 5, tau0=1.0)
    np.testing.assert_array_equal(gi.delta, merged.delta)


def test_field_reader_and_planet(tmp_path):
    run = write_run(tmp_path / "f", ncpu=3)
    params = read_variables(run)
    assert params["NX"] == NX and params["ASPECTRATIO"] == pytest.approx(H0)
    np.testing.assert_allclose(read_field(run, "dust1", "dens", 5, params), _density(5))
    p = read_planet(run, 5)
    assert p["phi"] == pytest.approx(PHI_P) and p["r"] == pytest.approx(1.0)


def test_fork_dust_names_and_left_hand(tmp_path):
    run = write_run(tmp_path / "fork", fork_names=True)
    t = read_fargo3d(run, 5, tau0=0.3, hand="L")
    assert t.hand == "L" and t.name == "fargo3d_fork_dust1_5_tau0.3_L"
    assert abs(_peak(t)[1] + BUMP_DPHI) <= 2 * np.pi / NX  # mirrored to φ < 0


def test_energy_field(tmp_path):
    iso = write_run(tmp_path / "iso", energy=lambda n: 0.07 * np.ones((NY, NX)))
    ref = read_fargo3d(write_run(tmp_path / "plain"), 5, tau0=3.0)
    t_iso = read_fargo3d(iso, 5, tau0=3.0)
    np.testing.assert_allclose(t_iso.delta, ref.delta, atol=1e-6)  # uniform c_s: no δT
    # adiabatic: e = Σ_gas T with T following the density bump → brighter residual at τ0 = 3
    adi = write_run(tmp_path / "adi", energy=lambda n: _density(n, 1.0) * (_density(n) / _density(0)) ** 0.4)
    t_adi = read_fargo3d(adi, 5, tau0=3.0)
    assert t_adi.delta.max() > 1.5 * ref.delta.max()


def test_missing_inputs_raise_clearly(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_fargo3d(tmp_path / "nope", 5, tau0=1.0)
    run = write_run(tmp_path / "run")
    with pytest.raises(FileNotFoundError, match=r"dust2.*output 5|fluid 'dust2'"):
        read_fargo3d(run, 5, tau0=1.0, fluid="dust2")
    with pytest.raises(FileNotFoundError, match="dust1dens7.dat"):
        read_fargo3d(run, 7, tau0=1.0)
    with pytest.raises(ValueError, match="tau0"):
        read_fargo3d(run, 5, tau0=-1.0)
    with pytest.raises(ValueError, match="unknown hand"):
        read_fargo3d(run, 5, tau0=1.0, hand="up")
    (run / "dust1dens5.dat").write_bytes(np.zeros(10).tobytes())
    with pytest.raises(ValueError, match="expected NX\\*NY\\*NZ"):
        read_fargo3d(run, 5, tau0=1.0)
    (run / "planet0.dat").unlink()
    with pytest.raises(FileNotFoundError, match="planet0.dat"):
        read_fargo3d(run, 0, tau0=1.0)
    (run / "variables.par").unlink()
    with pytest.raises(FileNotFoundError, match="variables.par"):
        read_fargo3d(run, 0, tau0=1.0)


def test_bad_domain_file(tmp_path):
    run = write_run(tmp_path / "bad")
    _, r_all = _edges()
    np.savetxt(run / "domain_y.dat", r_all[NGH:-NGH])  # ghosts missing
    with pytest.raises(ValueError, match="ghost"):
        read_fargo3d(run, 5, tau0=1.0)
