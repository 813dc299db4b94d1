"""The likelihood tables: a node grid's Fourier series is the product rule's exact transform inside
sigma_max, and a mirror template reading its partner's table equals a table of its own."""

import ducc0
import numpy as np

from spiralbayes.inference.posterior.perturbation import FastPerturbation, _lattice
from spiralbayes.inference.posterior.interpolation import _Cells, _TableBuilder
from spiralbayes.units import ARCSEC, TWO_PI
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile


def test_node_grids_hold_the_rules_exact_transform(setup):
    template = setup["template"]
    uv_max = float(np.max(setup["vis"].uv_distance))
    cells = _Cells.build(template, R_RANGE[1], uv_max)
    builder = _TableBuilder(cells, profile, R_RANGE[1] * ARCSEC * uv_max, cells.x_max, 1.5)
    rng = np.random.default_rng(5)
    radius = builder.sigma_max * np.sqrt(rng.uniform(0, 1, 400))
    angle = rng.uniform(0, TWO_PI, 400)
    sigma = np.stack([radius * np.cos(angle), radius * np.sin(angle)], -1)
    for r_p in (R_RANGE[0], 0.4):
        exact = ducc0.nufft.experimental.nu2nu(points_in=cells.fluxes(profile, r_p), coord_in=TWO_PI * cells.positions,
                                               coord_out=sigma, forward=False, epsilon=1e-12, nthreads=1)
        # the single-precision build and the double-precision reference (both stored as complex64)
        for grid in (builder(r_p), builder.reference(r_p)):
            series = ducc0.nufft.u2nu(grid=grid.astype(complex), coord=TWO_PI * builder.delta * sigma,
                                      forward=False, epsilon=1e-12, nthreads=1)
            assert np.max(np.abs(series - exact)) < 1e-6 * np.max(np.abs(exact))
        fast, reference = builder(r_p), builder.reference(r_p)
        assert fast.dtype == np.complex64
        assert np.linalg.norm(fast - reference) < 2e-6 * np.linalg.norm(reference)


def test_mirror_template_shares_its_partners_table(setup):
    vis, template = setup["vis"], setup["template"]
    mirror = template.mirror()
    args = (vis.u, vis.v, vis.weights, profile)
    right = FastPerturbation(*args, template, R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.05)
    shared = FastPerturbation(*args, mirror, R_RANGE, TRUE_GEOMETRY, mirror_of=right)
    own = FastPerturbation(*args, mirror, R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.05)
    assert shared.table is right.table and shared.nbytes == 0
    rng = np.random.default_rng(2)
    for _ in range(4):
        r_p, phi_p = rng.uniform(*R_RANGE), rng.uniform(0, 2 * np.pi)
        inc, PA = 40 + rng.normal(0, 2), 70 + rng.normal(0, 2)
        a, b = shared.disc_frame(r_p, phi_p, inc, PA), own.disc_frame(r_p, phi_p, inc, PA)
        assert np.sqrt(np.sum(vis.weights * np.abs(a - b) ** 2)) < 0.05  # within the tables' tolerance
        assert np.sqrt(np.sum(vis.weights * np.abs(a) ** 2)) > 10  # and not trivially small


def test_node_lattices_nest_when_halved():
    coarse, fine = _lattice(0.15, 0.6, 0.04, 6), _lattice(0.15, 0.6, 0.02, 6)
    assert coarse[0] >= 0 and fine[0] >= 0
    inside = coarse[(coarse >= 0.15) & (coarse <= 0.6)]
    assert all(np.min(np.abs(fine - r)) < 1e-12 for r in inside)  # the coarse nodes are reused...
    mids = 0.5 * (inside[1:] + inside[:-1])
    assert all(np.min(np.abs(fine - r)) < 1e-12 for r in mids)  # ...and so are the midpoints that checked them
    assert coarse[0] <= 0.15 - 0.04 and coarse[-1] >= 0.6 + 3 * 0.04  # room for the 6-point stencil


def test_node_grids_built_by_worker_processes_are_the_same_table(setup):
    """``processes=2`` builds each refinement round's nodes in forked workers: the same nodes, grids
    and refinement history as one process (reference: the in-process build)."""
    vis, template = setup["vis"], setup["template"]
    args = (vis.u, vis.v, vis.weights, profile, template, R_RANGE, TRUE_GEOMETRY)
    one = FastPerturbation(*args, rp_tolerance=0.005)  # two refinement rounds
    two = FastPerturbation(*args, rp_tolerance=0.005, processes=2)
    np.testing.assert_array_equal(one.table.r_nodes, two.table.r_nodes)
    np.testing.assert_array_equal(one.table.grids, two.table.grids)
    assert one.table.refinement == two.table.refinement and len(one.table.refinement) >= 2
    assert one.n_node_builds == two.n_node_builds > one.table.r_nodes.size  # midpoints of the last round too


def test_interpolated_grid_is_the_stencils_weighted_sum(setup):
    """The table's one-pass product over the stencil's grids, also added into another radius's sum
    (``out``), against the grid-by-grid sum (float64 reference), at radii near both ends and inside."""
    vis, template = setup["vis"], setup["template"]
    fp = FastPerturbation(vis.u, vis.v, vis.weights, profile, template, R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.05)
    table = fp.table
    for r_p in (R_RANGE[0], 0.3137, R_RANGE[1]):
        i0, w = table.stencil(r_p)
        exact = np.tensordot(w * 2.5, table.grids[i0:i0 + table.order].astype(complex), axes=1)
        fast = table.grid(r_p, scale=2.5)
        assert fast.dtype == np.complex64 and fast.shape == (table.N, table.N)
        np.testing.assert_allclose(fast, exact, rtol=0, atol=1e-6 * np.max(np.abs(exact)))
        np.testing.assert_allclose(table.grid_reference(r_p, 2.5), exact, rtol=0, atol=1e-6 * np.max(np.abs(exact)))
        # added into a grid already holding another radius's sum (a family's mass nodes)
        j0, v = table.stencil(0.5 * (R_RANGE[0] + r_p))
        other = np.tensordot(v * -1.5, table.grids[j0:j0 + table.order].astype(complex), axes=1)
        out = table.grid(0.5 * (R_RANGE[0] + r_p), scale=-1.5)
        assert table.grid(r_p, scale=2.5, out=out) is out
        np.testing.assert_allclose(out, exact + other, rtol=0, atol=2e-6 * np.max(np.abs(exact + other)))


def test_a_table_started_from_another_templates_step_meets_the_tolerance_at_every_midpoint(setup):
    """``refine_from``: a second template on the same radial grid starts at the first table's step and
    checks only the first table's worst midpoints. Reference: the error measured afresh at every
    midpoint, below the tolerance both where the check passes (same step) and where it fails (a
    stricter tolerance: the step is refined further)."""
    from spiralbayes.templates import make_template

    vis = setup["vis"]
    args = (vis.u, vis.v, vis.weights, profile)
    first = FastPerturbation(*args, setup["template"], R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.02)
    assert len(first.table.refinement[-1]["worst_midpoints_arcsec"]) == 8
    lighter = make_template(1.0, 0.3, 0.0, "R", n_x=160, n_phi=360)
    same = FastPerturbation(*args, lighter, R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.02, refine_from=first)
    assert same.table.step == first.table.step and len(same.table.refinement) == 1
    assert same.table.refinement[0]["midpoints_checked"] <= 8
    assert same.n_node_builds <= same.table.r_nodes.size + 8
    assert same.midpoint_errors()[1].max() <= 0.02
    strict = FastPerturbation(*args, lighter, R_RANGE, TRUE_GEOMETRY, rp_tolerance=0.0005, refine_from=first)
    assert strict.table.step < first.table.step and strict.table.refinement[0]["max_midpoint_error"] > 0.0005
    assert strict.midpoint_errors()[1].max() <= 0.0005
