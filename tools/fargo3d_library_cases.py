"""The FARGO3D hydrodynamic reference library of issue 21: its cases and their parameter files.

One table (:data:`CASES`, in run order) fixes every run; :func:`par_text` and :func:`planet_text`
write the FARGO3D ``.par`` and planet files from it, so the library is reproducible from this module
and the setups in ``tools/fargo3d/setups/``. Used by ``tools/make_fargo3d_library.py``.

Common set-up (issue 21's planning figures): 2-D cylindrical, r ∈ [0.4, 2.5] r_p log-spaced, square
cells at ``cells_per_h`` cells per H(r_p) (7.1 by default: 640 × 187 at H/r 0.07), H/r ∝ r^0.25,
Σ ∝ r^-1, ν = 1e-5, Stockholm damping within period ratio 1.15 of both edges, planet on a fixed
circular orbit at r = 1 (feels neither disc nor others), indirect term, frame corotating with the
planet, mass ramped over 5 orbits, 20 orbits, a field output every 5 orbits. Code units
G = M_* = r_p = 1 (one orbit = 2π).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi
Y_MIN, Y_MAX = 0.4, 2.5
SIGMA0 = 6.3661977237e-4
NU = 1.0e-5
FLARING = 0.25
SIGMA_SLOPE = 1.0
GAMMA = 1.4
STEPS_PER_ORBIT = 20          # DT = 1/20 orbit
ORBITS_PER_OUTPUT = 5


def h_text(h_p: float) -> str:
    """H/r as case and group names write it: two decimals, three where two would round it."""
    return f"{h_p:.2f}" if round(h_p, 2) == h_p else f"{h_p:.3f}"


@dataclass(frozen=True)
class Case:
    """One library run.

    Attributes
    ----------
    name : str
        Run and output-directory name.
    mu : float
        Planet mass in thermal masses, M_p/M_th with M_th = h_p³ M_*.
    h_p : float
        H/r at the planet.
    beta : float
        Cooling time in units of 1/Ω (0: locally isothermal, the ``fargo`` setup).
    stokes : float
        Stokes number of the one dust fluid (0: gas only).
    softening : float
        Potential softening in units of H(r_p) (FARGO3D ThicknessSmoothing).
    cells_per_h : float
        Cells per H(r_p) in both directions.
    orbits : float
        Run length in planet orbits.
    taper : float
        Mass-ramp length in orbits.
    role : str
        What the case is for.
    batch : str
        The run set it was planned in (``issue21``: the library; ``issue22``: 3 M_th at H/r 0.05 and
        0.10, added so that the 3 M_th morphology has references at more than one H/r; ``dust2``:
        dust at Stokes numbers 0.01 and 0.1 beside the library's 0.03; ``physics``: the disc physics
        the other runs share — surface-density slope, viscosity, masses and H/r between the bank's,
        and a run to 500 orbits; ``long2``: planets after 200 orbits at other masses and H/r than the
        ``orbits200`` pair's); ``continuum``: the space-filling design of :func:`continuum_cases` in
        (M_p, H/r, surface-density slope, α) for the template model continuous in disc physics.
    sigma_slope : float
        ``p`` of the initial ``Σ ∝ r^-p`` (FARGO3D SigmaSlope).
    nu : float
        Kinematic viscosity in code units (``α = ν / h_p²`` at the planet).
    continues : str
        Name of the case whose outputs this one restarts from (the same set-up run for longer); the
        driver copies that run's directory when this one has no outputs yet.
    """

    name: str
    mu: float
    h_p: float
    beta: float = 0.0
    stokes: float = 0.0
    softening: float = 0.6
    cells_per_h: float = 7.13
    orbits: float = 20.0
    taper: float = 5.0
    role: str = "library"
    batch: str = "issue21"
    sigma_slope: float = SIGMA_SLOPE
    nu: float = NU
    continues: str = ""

    @property
    def setup(self) -> str:
        """FARGO3D setup: ``fargo`` (isothermal), ``spiral_beta`` or ``spiral_dust`` (ours)."""
        if self.stokes > 0:
            return "spiral_dust"
        return "spiral_beta" if self.beta > 0 else "fargo"

    @property
    def group(self) -> str:
        """HDF5 group name of the reduced case."""
        tag = f"h{h_text(self.h_p)}_mu{self.mu:g}"
        if self.beta > 0:
            tag += f"_beta{self.beta:g}"
        if self.stokes > 0:
            tag += f"_st{self.stokes:g}"
        if self.role != "library":
            tag += f"_{self.role}"
        return tag

    @property
    def grid(self) -> tuple[int, int]:
        """(N_φ, N_r): N_φ a multiple of 16 giving ``cells_per_h``; square log-r cells."""
        nx = int(round(TWO_PI * self.cells_per_h / self.h_p / 16.0)) * 16
        ny = int(round(math.log(Y_MAX / Y_MIN) / (TWO_PI / nx)))
        return nx, ny

    @property
    def q_planet(self) -> float:
        """M_p/M_*."""
        return self.mu * self.h_p**3


def _case(name, mu, h_p, **kw) -> Case:
    return Case(name=name, mu=mu, h_p=h_p, **kw)


CASES: list[Case] = [  # run order: the most distinct cases per CPU hour first (see tools/README.md)
    _case("lib_mu1_h007", 1.0, 0.07),
    _case("lib_mu0.3_h007", 0.3, 0.07),
    _case("relax_test_beta10", 0.0, 0.07, beta=10.0, orbits=2.0, role="relaxtest"),
    _case("lib_mu1_h010", 1.0, 0.10),
    _case("lib_mu0.3_h010", 0.3, 0.10),
    _case("lib_mu1_h007_beta10", 1.0, 0.07, beta=10.0),
    _case("lib_mu3_h007", 3.0, 0.07),
    _case("lib_mu0.3_h007_beta10", 0.3, 0.07, beta=10.0),
    _case("lib_mu1_h007_st0.03", 1.0, 0.07, stokes=0.03),
    _case("lib_mu0.1_h007", 0.1, 0.07),
    _case("lib_mu1_h007_soft0.35", 1.0, 0.07, softening=0.35, role="soft0.35"),
    _case("lib_mu1_h005", 1.0, 0.05),
    _case("lib_mu0.3_h005", 0.3, 0.05),
    _case("lib_mu1_h007_res14", 1.0, 0.07, cells_per_h=14.26, role="res14"),
    # longer evolution (gap growth): the 1 and 3 M_th runs continued to 200 orbits
    _case("lib_mu1_h007_long", 1.0, 0.07, orbits=200.0, role="orbits200"),
    _case("lib_mu3_h007_long", 3.0, 0.07, orbits=200.0, role="orbits200"),
    # a second run set (issue 22): the 3 M_th planet at the two other H/r, so that leaving one run
    # set out still leaves an early-time 3 M_th reference
    _case("lib_mu3_h010", 3.0, 0.10, batch="issue22"),
    _case("lib_mu3_h005", 3.0, 0.05, batch="issue22"),
    # a third run set (dust2): Stokes numbers 0.01 and 0.1 beside the library's 0.03, at 1 M_th first
    # and then 0.3 and 3 M_th, so that the dust morphology's dependence on grain size is measured
    _case("lib_mu1_h007_st0.01", 1.0, 0.07, stokes=0.01, batch="dust2"),
    _case("lib_mu1_h007_st0.1", 1.0, 0.07, stokes=0.1, batch="dust2"),
    _case("lib_mu0.3_h007_st0.01", 0.3, 0.07, stokes=0.01, batch="dust2"),
    _case("lib_mu0.3_h007_st0.1", 0.3, 0.07, stokes=0.1, batch="dust2"),
    _case("lib_mu3_h007_st0.01", 3.0, 0.07, stokes=0.01, batch="dust2"),
    _case("lib_mu3_h007_st0.1", 3.0, 0.07, stokes=0.1, batch="dust2"),
    # the fastest-drifting grains continued to 200 orbits (restarted from the 20-orbit run's last
    # output): the dust's evolved gap and ring
    _case("lib_mu1_h007_st0.1_long", 1.0, 0.07, stokes=0.1, orbits=200.0, role="orbits200", batch="dust2"),
    # a fourth run set (physics, issue 31): what every run above holds fixed — the surface-density
    # slope (0.5 and 1.5 beside 1), the viscosity (alpha 2e-4 and 2e-2 beside 2e-3 at H/r 0.07),
    # masses and H/r between the bank's — at 20 orbits, then the 1 M_th gas run to 500 orbits
    _case("lib_mu1_h007_slope0.5", 1.0, 0.07, sigma_slope=0.5, role="slope0.5", batch="physics"),
    _case("lib_mu1_h007_slope1.5", 1.0, 0.07, sigma_slope=1.5, role="slope1.5", batch="physics"),
    _case("lib_mu1_h007_nu1e-6", 1.0, 0.07, nu=1e-6, role="nu1e-06", batch="physics"),
    _case("lib_mu1_h007_nu1e-4", 1.0, 0.07, nu=1e-4, role="nu1e-04", batch="physics"),
    _case("lib_mu0.5_h006", 0.5, 0.06, batch="physics"),
    _case("lib_mu2_h008", 2.0, 0.08, batch="physics"),
    _case("lib_mu1_h007_orbits500", 1.0, 0.07, orbits=500.0, role="orbits500", batch="physics"),
    # a fifth run set (long2): planets evolved for 200 orbits beside the H/r 0.07 1 and 3 M_th pair, so
    # that leaving one set out still leaves a deep, evolved gap: 1 and 3 M_th at H/r 0.10 (the 3 M_th
    # one vortex-dominated, as at 20 orbits), then 2 M_th at 0.07 and 3 M_th at 0.05
    _case("lib_mu3_h010_long", 3.0, 0.10, orbits=200.0, role="orbits200", batch="long2"),
    _case("lib_mu1_h010_long", 1.0, 0.10, orbits=200.0, role="orbits200", batch="long2"),
    _case("lib_mu2_h007_long", 2.0, 0.07, orbits=200.0, role="orbits200", batch="long2"),
    _case("lib_mu3_h005_long", 3.0, 0.05, orbits=200.0, role="orbits200", batch="long2"),
]


# The continuum design's box: what the physics-continuous template model is to span.
CONTINUUM_BOX = {"mu": (0.1, 3.0), "h_p": (0.04, 0.12), "sigma_slope": (0.5, 1.5), "alpha": (1e-4, 1e-2)}
CONTINUUM_SEED = 53     # fixes the scrambled Sobol sequence, so every session extends the same design
CONTINUUM_AGES = (200.0, 1000.0)


def continuum_point(u) -> dict:
    """Map a point ``u`` of the unit 4-cube to rounded disc physics in :data:`CONTINUUM_BOX`.

    ln M_p, H/r, the slope p and log10 α are uniform in their ranges; the values are rounded (M_p to
    two significant figures, H/r to 0.01, p to 0.05, log10 α to 0.1) so that names stay short and
    the FARGO3D parameter files reproduce them exactly.
    """
    lo, hi = (math.log(v) for v in CONTINUUM_BOX["mu"])
    mu = float(f"{math.exp(lo + u[0] * (hi - lo)):.2g}")
    h0, h1 = CONTINUUM_BOX["h_p"]
    h_p = round(h0 + u[1] * (h1 - h0), 2)
    p0, p1 = CONTINUUM_BOX["sigma_slope"]
    slope = round((p0 + u[2] * (p1 - p0)) * 20.0) / 20.0
    a0, a1 = (math.log10(v) for v in CONTINUUM_BOX["alpha"])
    alpha = 10.0 ** round(a0 + u[3] * (a1 - a0), 1)
    return {"mu": mu, "h_p": h_p, "sigma_slope": slope, "alpha": alpha}


def continuum_cases(n: int = 32, n_aged: int = 4) -> list[Case]:
    """The ``continuum`` run set: the first ``n`` points of a scrambled Sobol sequence, then ages.

    A Sobol sequence's every prefix of 2^k points is balanced in every parameter, so running the
    cases in table order gives the widest coverage for the CPU hours spent so far; a later session
    that raises ``n`` extends the same design (fixed seed) instead of starting another. The first
    ``n_aged`` points with H/r ≥ 0.07 (the cheap ones: cost per orbit ∝ (H/r)^-2) are then continued
    to each age of :data:`CONTINUUM_AGES` (orbits), each from the previous age's run.

    Viscosity is set by α at the planet (ν = α h_p²), so that a point's gap depth depends on α
    and M_p rather than on how ν compares with the local sound speed.
    """
    from scipy.stats import qmc   # the tools' environment has scipy; the module stays importable without

    u = qmc.Sobol(d=4, scramble=True, seed=CONTINUUM_SEED).random(n)
    cases: list[Case] = []
    for k, uk in enumerate(u):
        pt = continuum_point(uk)
        nu = pt["alpha"] * pt["h_p"] ** 2
        role = f"slope{pt['sigma_slope']:g}_alpha{pt['alpha']:.1e}"
        cases.append(_case(f"cont{k:02d}_mu{pt['mu']:g}_h{pt['h_p']:.2f}_{role}", pt["mu"], pt["h_p"],
                           sigma_slope=pt["sigma_slope"], nu=nu, role=role, batch="continuum"))
    aged = [c for c in cases if c.h_p >= 0.07][:n_aged]
    previous = {c.name: c.name for c in aged}
    for orbits in CONTINUUM_AGES:
        for c in aged:
            name = f"{c.name}_orbits{orbits:g}"
            cases.append(_case(name, c.mu, c.h_p, sigma_slope=c.sigma_slope, nu=c.nu, orbits=orbits,
                               role=f"{c.role}_orbits{orbits:g}", batch="continuum",
                               continues=previous[c.name]))
            previous[c.name] = name
    return cases


try:
    CONTINUUM = continuum_cases()
except ImportError:   # pragma: no cover - scipy missing: the earlier run sets still work
    CONTINUUM = []
CASES += CONTINUUM

# Aged, massive planets between the library's 200-orbit 3 M_th runs at H/r 0.05 and 0.07: the runs
# the learned model recovers worst when they are held out (docs/templates.md, "Leave one run out")
# have no neighbour at their mass and age. Run from scratch to the age (no 20-orbit stop), in the
# continuum's file.
AGED = [_case("aged00_mu3_h0.06_slope1_alpha2.0e-03_orbits200", 3.0, 0.06, sigma_slope=1.0, nu=2.0e-3 * 0.06**2,
              orbits=200.0, role="slope1_alpha2.0e-03_orbits200", batch="continuum")]
CASES += AGED


def _near(k: int, mu: float, h_p: float, slope: float, alpha: float) -> Case:
    role = f"slope{slope:g}_alpha{alpha:.1e}"
    return _case(f"near{k:02d}_mu{mu:g}_h{h_text(h_p)}_{role}", mu, h_p, sigma_slope=slope, nu=alpha * h_p**2,
                 role=role, batch="continuum")


# 20-orbit neighbours of the runs the learned model recovers worst when they are held out
# (docs/templates.md, "Leave one run out"): the library's 3 M_th planet at H/r 0.07 (no other
# 20-orbit planet above 2.1 M_th between H/r 0.05 and 0.11), the low-α massive planet at H/r 0.11 and
# the lightest planet at H/r 0.12. Cheapest and nearest first; α ≥ 2e-3 for the massive ones, whose
# lower-viscosity neighbours at H/r 0.08–0.10 grew vortices.
NEAR = [_near(0, 3.0, 0.06, 1.0, 2.0e-3), _near(1, 3.0, 0.08, 1.0, 5.0e-3), _near(2, 2.5, 0.07, 0.7, 2.0e-3),
        _near(3, 1.5, 0.11, 1.2, 2.0e-4), _near(4, 0.2, 0.12, 1.0, 1.0e-3), _near(5, 3.0, 0.07, 1.3, 5.0e-3),
        # with those 60 training runs, the two below 0.6 are massive planets at H/r 0.11: α 1e-2 and 1.3e-4
        _near(6, 3.0, 0.11, 1.0, 5.0e-3), _near(7, 2.5, 0.12, 0.7, 1.0e-2), _near(8, 1.0, 0.12, 1.4, 1.3e-4),
        _near(9, 2.0, 0.10, 1.2, 1.0e-2),
        # with those 64 (and cont01's 1000-orbit age) the two below 0.6 are the 1.4 M_th planet at H/r 0.11,
        # α 1.3e-4 (3 % below every other run's α) and the 0.24 M_th planet at H/r 0.04 (one other run there)
        _near(10, 1.7, 0.11, 1.3, 1.0e-4), _near(11, 0.3, 0.04, 0.8, 5.0e-4),
        # near10 grew vortices (not a training run): a lighter planet at that viscosity
        _near(12, 1.2, 0.11, 1.4, 1.0e-4),
        # with near11 and near12 (67 runs), the low-α planets at H/r 0.11 (near12 and the 1.4 M_th run) are each
        # other's only neighbours: four more around them (each 2-4 CPU-min at 20 orbits)
        _near(13, 1.3, 0.11, 1.3, 1.2e-4), _near(14, 1.0, 0.10, 1.4, 1.0e-4), _near(15, 1.4, 0.12, 1.4, 1.0e-4),
        _near(16, 1.2, 0.11, 1.1, 1.5e-4),
        # the physics set's α 2e-2 planet held out, the others' box stops at α 1e-2 and its mass is missed:
        # two 20-orbit planets at α 2e-2 beside it
        _near(17, 1.3, 0.08, 1.0, 2.0e-2), _near(18, 0.6, 0.06, 1.2, 2.0e-2),
        # without the four transients (LATE) that planet is still predicted at half its mass: one more α 2e-2
        # planet between near17 and near18
        _near(19, 0.9, 0.065, 0.9, 2.0e-2)]
CASES += NEAR

# Training runs whose δΣ/Σ still changes by more than 25 % in their last 5 orbits at 20 orbits, continued
# to 40 orbits to see whether their maps settle or are on the way to the vortices that their neighbours
# grow (near10, near15): cont13 (38 %, the one run the learned model recovered below 0.6 when held out),
# then near03 (39 %, below 0.6 once cont13 is not trained on), near06 (36 %) and near13 (27 %).
def _later(c: Case, orbits: float = 40.0) -> Case:
    return _case(f"{c.name}_orbits{orbits:g}", c.mu, c.h_p, sigma_slope=c.sigma_slope, nu=c.nu, orbits=orbits,
                 role=f"{c.role}_orbits{orbits:g}", batch="continuum", continues=c.name)


LATE = [_later(c) for c in CASES if c.name in ("cont13_mu1.4_h0.11_slope1.4_alpha1.3e-04",
                                                "near03_mu1.5_h0.11_slope1.2_alpha2.0e-04",
                                                "near06_mu3_h0.11_slope1_alpha5.0e-03",
                                                "near13_mu1.3_h0.11_slope1.3_alpha1.2e-04")]
CASES += LATE
BY_NAME = {c.name: c for c in CASES}


def n_outputs(case: Case) -> int:
    """Number of the last field output of a complete run."""
    ninterm = 2 if case.role == "relaxtest" else ORBITS_PER_OUTPUT * STEPS_PER_ORBIT
    return int(round(case.orbits * STEPS_PER_ORBIT)) // ninterm


def planet_text(case: Case) -> str:
    """FARGO3D planet file: one planet at r = 1 on a fixed circular orbit."""
    return (f"# spiralbayes library (issue 21): M_p = {case.mu:g} M_th, M_th = h_p^3 M_*, h_p = {case.h_p:g}\n"
            "# Name  Distance  Mass  Accretion  FeelsDisk  FeelsOthers\n"
            f"Planet  1.0  {case.q_planet:.6e}  0.0  NO  NO\n")


def par_text(case: Case, output_dir: str, planet_file: str) -> str:
    """FARGO3D ``.par`` file of ``case``, writing its outputs to ``output_dir``."""
    nx, ny = case.grid
    steps = int(round(case.orbits * STEPS_PER_ORBIT))
    ninterm = steps // n_outputs(case)   # relaxation test: every 1/10 orbit, planet of zero mass
    # (a zero-mass planet rather than PlanetConfig NONE, which crashes this FARGO3D version)
    lines = [
        f"Setup\t\t\t{case.setup}",
        f"# spiralbayes library case {case.name} (tools/fargo3d_library_cases.py, issue 21)",
        f"AspectRatio\t\t{case.h_p:g}",
        f"FlaringIndex\t\t{FLARING:g}",
        f"Sigma0\t\t\t{SIGMA0:.10e}",
        f"SigmaSlope\t\t{case.sigma_slope:g}",
        f"Nu\t\t\t{case.nu:.3e}",
        "Noise\t\t\t0.0",
        "DampingZone\t\t1.15",
        "TauDamp\t\t\t0.3",
        f"PlanetConfig\t\t{planet_file}",
        f"MassTaper\t\t{case.taper * TWO_PI:.10f}",
        f"ThicknessSmoothing\t{case.softening:g}",
        "RocheSmoothing\t\t0.0",
        "Eccentricity\t\t0.0",
        "ExcludeHill\t\tno",
        "IndirectTerm\t\tYes",
        f"Nx\t\t\t{nx}",
        f"Ny\t\t\t{ny}",
        "Spacing\t\t\tLog",
        "Xmin\t\t\t-3.14159265358979323844",
        "Xmax\t\t\t3.14159265358979323844",
        f"Ymin\t\t\t{Y_MIN:g}",
        f"Ymax\t\t\t{Y_MAX:g}",
        "Frame\t\t\tC",
        "OmegaFrame\t\t1.0",
        f"DT\t\t\t{TWO_PI / STEPS_PER_ORBIT:.12f}",
        f"Ninterm\t\t\t{ninterm}",
        f"Ntot\t\t\t{steps}",
        f"OutputDir\t\t{output_dir}",
        "PlotLog\t\t\tyes",
    ]
    if case.setup == "spiral_beta":
        lines += [f"Gamma\t\t\t{GAMMA:g}", f"BetaCool\t\t{case.beta:g}",
                  f"EPert\t\t\t{0.1 if case.role == 'relaxtest' else 0.0:g}"]
    if case.setup == "spiral_dust":
        lines += [f"Invstokes1\t\t{1.0 / case.stokes:.6g}", "Epsilon\t\t\t0.01"]
    return "\n".join(lines) + "\n"
