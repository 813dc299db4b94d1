"""Writes the tutorial notebooks from the cells below (stored without outputs; the docs build runs them).

Run ``python docs/tutorials/_make.py`` after editing a tutorial here; the notebooks are the published form.
"""

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).parent

SETUP = '''%matplotlib inline
import os

import numpy as np

import spiralbayes as sb

# The docs build runs this notebook at a reduced size (seconds); SPIRALBAYES_TUTORIAL_SIZE=full runs the
# analysis at the size you would use on your own data.
FULL = os.environ.get("SPIRALBAYES_TUTORIAL_SIZE", "reduced") == "full"
FRANK = {} if FULL else {"N": 100}  # frank's collocation points: the paper's 200, or 100 for speed'''


def md(text):
    return new_markdown_cell(text.strip("\n"))


def code(text):
    return new_code_cell(text.strip("\n"))


TUTORIALS = {}

TUTORIALS["search_your_disc"] = [
    md('''
# Search your disc: from a uvtable to the verdict

This tutorial runs the whole single-disc search of Stevenson et al. (2024) on a synthetic observation:
read the visibilities, fit the axisymmetric disc with frank, scan spiral templates over every planet
position, and decide with the three tests — ΔBIC against the axisymmetric disc (test 1), a compact
and handed peak (test 2), and the competing non-spiral asymmetries (test 3). Every step is one call of
`import spiralbayes as sb`.
'''),
    code(SETUP),
    md('''
## 1. The data

A synthetic ALMA observation with the Taurus survey's set-up (C-6, 1.33 mm, 50 µJy/beam): a disc at
140 pc, inclined 30° at PA 60°, with a 3 M_th planet (τ0 = 3, β = 10) at 60 au and φ_p = 90°. It is
written to a uvtable (columns u [λ], v [λ], Re V [Jy], Im V [Jy], weight [Jy⁻²]) and read back, as your
own data would be. A Measurement Set is read the same way (`sb.load_visibilities("disc.ms")`, with the
`ms` extra: python-casacore), as are `.npz` and `.h5` files.
'''),
    code('''
import tempfile
from pathlib import Path

work = Path(tempfile.mkdtemp(prefix="spiralbayes-tutorial-"))
geometry = sb.DiscGeometry(inc=30.0, PA=60.0)
truth = {"r_p": 60 / 140, "phi_p": np.radians(90.0)}
planet = sb.make_template(mass=3.0, tau0=3.0, beta=10.0, hand="R")
simulated = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0, tau_ref=3.0), geometry, planet,
                                    seed=4, **truth)
sb.save_visibilities(simulated, work / "disc.txt")

vis = sb.load_visibilities(work / "disc.txt")
print(vis.n, "visibilities")
'''),
    md('''
## 2. The axisymmetric disc

frank fits the deprojected brightness profile non-parametrically, with the paper's hyperparameters;
the geometry (inclination, position angle, phase centre) is given here — leave it out and
`fit_axisymmetric` fits it first. The binned visibilities show how well the profile reproduces the
data: the spiral is what is left.
'''),
    code('''
disc = sb.fit_axisymmetric(vis, geometry, progress=False, **FRANK)
print(f"flux {disc.total_flux:.3f} Jy, R_eff {disc.R_eff():.2f} arcsec")
sb.plotting.plot_binned_visibilities(vis, disc)
'''),
    code('''
sb.plotting.plot_profile(disc, distance=140.0)
'''),
    md('''
## 3. The template scan

The default bank holds the paper's 64 templates (mass, τ0, β, hand) at three aspect ratios and in three
morphologies. Here the family with τ0 = 3, β = 10, H/r = 0.07 at 1 and 3 M_th (12 templates) is
scanned over a grid of planet radii and 90 azimuths; with no prior knowledge, scan the whole bank
(`sb.default_bank()`, about 40 s for 1e5 visibilities on 2 cores).
'''),
    code('''
templates = sb.default_bank().select(mass=[1.0, 3.0], tau0=3.0, beta=10.0, h_p=0.07)
r_p = np.linspace(0.1, 0.7, 25 if FULL else 13)  # arcsec
result = sb.scan(vis, disc, templates, r_p=r_p, distance=140.0, progress=False)
sb.plotting.plot_heatmap_pair(result, "wake_m3_tau3_b10_h0.07_R", "wake_m3_tau3_b10_h0.07_L")
'''),
    md('''
The right-handed template (left panel) peaks at the planet; its mirror image (right panel) does not —
the handedness that test 2 asks for.

## 4. The verdict

`sb.detect` applies tests 1 and 2 to the scan. Test 3 needs the competing asymmetry models — a
geometry error, an arc or vortex, a lopsided disc, an eccentric ring, an m = 2 pattern — fitted to the
same visibilities with `sb.fit_alternatives`.
'''),
    code('''
alternatives = sb.fit_alternatives(vis, disc)
verdict = sb.detect(result, alternatives=alternatives)
print(verdict.summary())
'''),
    code('''
sb.plotting.plot_residual_comparison(vis, disc, result, alternatives, templates)
'''),
    md('''
The residual images compare the data minus the axisymmetric disc with the best spiral and the best
competing model. Save any result for later (`result.save(...)`, `verdict.save(...)`; each class has
`load`), or run the same analysis from the command line: `spiralbayes scan config.toml` writes the
scan, the verdict and these figures.
'''),
]

TUTORIALS["limits"] = [
    md('''
# What can be ruled out: limits, robust morphology, Table 3, forecasts

When no spiral is detected, the scan still says which planets would have been: the **exclusion
limits**. This tutorial computes them on a planet-free observation, robust to the spiral's
morphology, reads them as the paper's Table 3 does, and forecasts what a longer observation would
detect.
'''),
    code(SETUP),
    md('''
## 1. A disc without a planet

The Taurus set-up of the paper's Table 3 (C-6, 1.33 mm, 50 µJy/beam), a disc at 140 pc.
'''),
    code('''
geometry = sb.DiscGeometry(inc=30.0, PA=60.0)
vis = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0, tau_ref=3.0), geometry, seed=11)
disc = sb.fit_axisymmetric(vis, geometry, progress=False, **FRANK)
'''),
    md('''
## 2. Scan one template family in its three morphologies

A limit is a statement about a family of templates (τ0, β, H/r), at every mass and both hands. No
template is the true spiral, so the default bank carries each family in three morphologies
(compromise, hydro, wakeflow); a mass counts as ruled out only where **every** morphology rules it
out — the robust limit.
'''),
    code('''
family = sb.default_bank().select(tau0=0.3, beta=10.0, h_p=0.07)
print(len(family), "templates: 4 masses x 2 hands x 3 morphologies")
result = sb.scan(vis, disc, family, r_p=np.linspace(0.1, 0.5, 25 if FULL else 9), distance=140.0,
                 progress=False)
print(sb.detect(result).summary())
'''),
    md('''
## 3. Exclusion limits

`compute_limits` gives, at every radius, the smallest planet mass the data rule out at 95 %
confidence (`M_lim`). Radii that the data cannot judge are flagged, not excluded: inside one beam
("unresolved"), beyond the bright disc, or near a detected planet or asymmetry (give the verdict as
`planets=`).
'''),
    code('''
limits = sb.compute_limits(result, vis=vis, axisymmetric=disc, distance=140.0)
print("morphologies:", limits.morphologies)
print(limits.summary())
'''),
    code('''
sb.plotting.plot_mass_radius(limits)
'''),
    md('''
## 4. Table 3

The paper's Table 3 lists, per disc, the radii where planets of at least 3 and at least 1 M_th are
ruled out, with their Jupiter masses. `excluded_ranges` gives those ranges [arcsec]; the price of
robustness says how much higher the robust limit is than the compromise morphology's alone.
`spiralbayes limits config.toml` writes the same table (ECSV and Markdown).
'''),
    code('''
for mass in (3.0, 1.0):
    ranges = limits.excluded_ranges(mass=mass)
    text = ", ".join(f"{a * 140:.0f}-{b * 140:.0f} au" for a, b in ranges) or "none"
    print(f">= {mass:g} M_th ruled out at: {text}")
print("price of robustness (median):", limits.price_of_robustness_median())
'''),
    md('''
## 5. Forecast: would a longer observation detect it?

`sb.forecast` predicts, for one template at one radius, the expected Δχ² of a planet in a given
observing set-up and the probability that it passes test 1 — without simulating noise.
'''),
    code('''
# the compromise morphology at the Taurus wavelength [m]
template = sb.make_template(mass=0.3, tau0=0.3, beta=10.0, h_p=0.07, hand="R", wavelength=1.33e-3)
for setup in ("taurus", "fiducial", "high_sensitivity"):
    print(sb.forecast(disc, template, 0.3, setup, geometry=geometry, distance=140.0).summary())
'''),
]

TUTORIALS["alternatives"] = [
    md('''
# Is it really a spiral? The alternatives, and what to do when one wins

A spiral template can fit structure that is not a spiral: a phase-centre error, a vortex, a lopsided
or eccentric disc. Test 3 fits each of these competing models to the same visibilities and accepts
the spiral only if it beats the best of them by ΔBIC > 10. This tutorial plants an impostor — a
phase-centre error — and follows the verdict's advice.
'''),
    code(SETUP),
    md('''
## 1. An impostor: a disc observed 10 mas off its assumed centre

The disc has no planet, but its true centre is 10 mas east of where the analysis assumes it.
'''),
    code('''
nominal = sb.DiscGeometry(inc=30.0, PA=60.0)
true_geometry = sb.DiscGeometry(inc=30.0, PA=60.0, dRA=0.010)  # arcsec
vis = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0, tau_ref=3.0), true_geometry, seed=3)
disc = sb.fit_axisymmetric(vis, nominal, progress=False, **FRANK)
templates = sb.default_bank().select(tau0=3.0, beta=10.0, h_p=0.07, mass=[0.3, 1.0, 3.0])
result = sb.scan(vis, disc, templates, r_p=np.linspace(0.1, 0.6, 21 if FULL else 11), distance=140.0,
                 progress=False)
print(sb.detect(result).summary())
'''),
    md('''
## 2. Test 3: the competing models

The scan alone may find a strong peak. `fit_alternatives` fits the five alternatives; `detect` with
them applies test 3 and names the winner.
'''),
    code('''
alternatives = sb.fit_alternatives(vis, disc)
print(alternatives.summary())
verdict = sb.detect(result, alternatives=alternatives)
print(verdict.summary())
'''),
    code('''
sb.plotting.plot_residual_comparison(vis, disc, result, alternatives, templates)
'''),
    md('''
## 3. When the geometry wins: the follow-up

A geometry alternative that wins means the disc's centre or orientation is off. The follow-up refits
frank at the fitted geometry, scans again and repeats test 3; a real spiral survives it, an impostor
does not.
'''),
    code('''
follow_up = sb.rescan_at_fitted_geometry(vis, disc, templates, alternatives, scan_result=result,
                                         distance=140.0, frank_kwargs=FRANK)
g = follow_up.geometry
print(f"fitted phase centre: dRA = {g.dRA * 1e3:.1f} mas, dDec = {g.dDec * 1e3:.1f} mas (truth 10, 0)")
print(follow_up.verdict.summary())
'''),
    md('''
What to do when another alternative wins:

* **arc / vortex**: a compact non-spiral feature (or a spiral with a strong peak at the planet); look
  at the residual image and the arc's fitted position. `detect_with_planet_peak` in
  `spiralbayes.inference.detection.planet_peak` scores the spiral with a compact peak at the planet.
* **lopsided or m = 2**: a global asymmetry; the spiral search is not the right model, and limits near
  the asymmetry's annulus are flagged (`compute_limits(..., planets=verdict)`).
* **eccentric ring**: an eccentric disc or a wrong inclination; refit the geometry.
'''),
    md('''
## 4. A planet or a vortex? The candidate and the posterior odds

At low optical depth most of a planet's signal is its compact peak at the planet, which an arc fits as
well; and a vortex is a compact source no spiral template fits. Rather than a bare "no spiral", the
verdict then names a **candidate**: the compact source's place and flux, the models that explain it, and
what to do next. Here a vortex (a dust-trapping arc, 0.3 times the disc's brightness, 17° wide) sits at
56 au in a disc of low optical depth (τ0 = 0.3).
'''),
    code('''
import tempfile
from pathlib import Path

work = Path(tempfile.mkdtemp(prefix="spiralbayes-odds-"))
disc_model = sb.DiscModel(distance=140.0, tau_ref=0.3)
vortex = sb.simulate.vortex_arc(disc_model.profile(1.33e-3), r_c=0.4, phi_c=np.radians(120.0), width_r=0.03,
                                width_phi=0.3, contrast=0.3)
vis = sb.simulate_observation("taurus", disc_model, nominal, vortex, seed=7)
disc = sb.fit_axisymmetric(vis, nominal, progress=False, **FRANK)
templates = sb.default_bank().select(tau0=0.3, beta=0.0, h_p=0.07, mass=[1.0, 3.0])
result = sb.scan(vis, disc, templates, r_p=np.linspace(0.1, 0.6, 21 if FULL else 11), distance=140.0,
                 progress=False)
verdict = sb.detect(result, alternatives=sb.fit_alternatives(vis, disc), vis=vis, axisymmetric=disc,
                    templates=templates)
print(verdict.outcome)
print(verdict.compact_source["explained_by"], f"{verdict.compact_source['flux_mJy']:.2f} mJy")
'''),
    md('''
The posterior odds weigh the explanations: the arc/vortex and the eccentric ring are sampled beside the
planet, each with its own position, shape and amplitude and the disc geometry, and each gets its
evidence as the planet's does. `model_probabilities` holds P(planet), P(arc/vortex), P(eccentric ring)
and P(no asymmetry); `model_probability_errors` their Monte Carlo errors. (The run here is short so
that the page builds quickly.)
'''),
    code('''
sampling = sb.SamplingSettings(run_name="odds") if FULL else sb.SamplingSettings(
    run_name="odds", n_walkers=12, n_steps=30, convergence="ignore", evidence_draws=100, max_chains=1)
post = sb.sample_posterior(vis, disc, templates, scan_result=result, priors=sb.Priors.default(disc, r_p=(0.2, 0.55)),
                           settings=sampling, alternatives=("arc", "eccentric_ring"), chains_dir=work,
                           progress=False)
print(post.odds_sentence())
'''),
    md('''
For a candidate that a planet's spiral explains (tests 1 and 2 pass, test 3 does not decide), the
summary also says how many times deeper the data must be for test 3 to pass if it is a planet
(`verdict.compact_source["deeper_time_factor"]`).
'''),
]

TUTORIALS["posterior"] = [
    md('''
# The posterior, with the disc geometry as a nuisance

A detection says *that* a spiral is there; the posterior says *where* the planet is, how bright its
spiral is, and how sure we are — with the disc's inclination, position angle and phase centre sampled
alongside, and frank's brightness profile integrated out at every sampled geometry (Stevenson et al.
2024, Appendix A). This tutorial fits frank at a geometry 3° off in inclination and lets the
posterior find the right one.
'''),
    code(SETUP),
    md('''
## 1. Data, and a profile fitted at the wrong inclination

A 3 M_th planet at 60 au (0.43″ at 140 pc) and φ_p = 90°, in a disc inclined 30°; frank is fitted
assuming 33°.
'''),
    code('''
import tempfile
from pathlib import Path

work = Path(tempfile.mkdtemp(prefix="spiralbayes-posterior-"))
truth = {"r_p": 60 / 140, "phi_p": np.radians(90.0), "inc": 30.0, "PA": 60.0, "dRA": 0.0, "dDec": 0.0}
templates = [sb.make_template(mass=3.0, tau0=3.0, beta=10.0, hand=hand, wavelength=1.33e-3) for hand in "RL"]
vis = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0, tau_ref=3.0),
                              sb.DiscGeometry(inc=30.0, PA=60.0), templates[0],
                              r_p=truth["r_p"], phi_p=truth["phi_p"], seed=4)
disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=33.0, PA=60.0), progress=False, **FRANK)
result = sb.scan(vis, disc, templates, r_p=np.linspace(0.2, 0.6, 17 if FULL else 9), distance=140.0,
                 progress=False)
print(sb.detect(result).summary())
'''),
    md('''
## 2. Priors and sampling

`Priors.default` centres the geometry priors on the frank fit's geometry, with the widths given
(inclination and PA [deg], phase centre [arcsec]); the planet's radius prior is uniform over the range
given [arcsec] and its azimuth over the circle. Every option of the sampler is a field of
`SamplingSettings` (`help(sb.SamplingSettings)` lists them with their defaults). The run here is
short so that the page builds quickly: for science leave `n_steps` unset, and the sampler runs until the
autocorrelation test says the chains have converged.
'''),
    code('''
priors = sb.Priors.default(disc, r_p=(0.3, 0.55), widths={"inc": 5.0, "PA": 3.0, "dRA": 0.02, "dDec": 0.02})
if FULL:
    sampling = sb.SamplingSettings(run_name="tutorial")  # until converged
else:
    sampling = sb.SamplingSettings(run_name="tutorial", n_walkers=16, n_steps=40, convergence="ignore",
                                   evidence_draws=100)
sampled = templates if FULL else templates[:1]  # the mirror template too, at full size
post = sb.sample_posterior(vis, disc, sampled, scan_result=result, priors=priors, settings=sampling,
                           chains_dir=work, progress=False)
print(post.verdict)
'''),
    md('''
## 3. What the posterior says

The inclination comes back to the truth although frank was fitted 3° off: the profile is refitted
(marginalised) at every sampled geometry. The corner plot shows the planet's position and the geometry
together, with the truth marked.
'''),
    code('''
print(post.summary())  # the verdict, then the percentiles of the most probable template's parameters
'''),
    code('''
sb.plotting.plot_corner(post, truths=truth)
'''),
    md('''
`post.template_probabilities` gives each template's probability given a planet, and `post.p_planet`
the probability of a planet against the disc alone (from the evidences). `post.save(...)` writes the
result, `post.to_inference_data()` converts the chains for ArviZ, and `spiralbayes sample config.toml`
runs the same from the command line.
'''),
]

TUTORIALS["survey"] = [
    md('''
# A survey on a laptop and on a cluster

`sb.run_survey` runs the whole single-disc search — frank, the scan, test 3's alternatives, the verdict,
the exclusion limits and the posterior of candidates — over every disc of a survey file, and writes one
table. The same file runs on a laptop (serially or on a local Dask cluster) and on a batch cluster;
only the `scheduler` changes.
'''),
    code(SETUP.replace("import numpy as np\n\n", "")),
    md('''
## 1. The survey file

Two synthetic, planet-free discs observed with the Taurus set-up: a `simulate` entry writes each disc's
data at `path` when the file is missing (for real data, give the path of a Measurement Set, uvtable,
`.npz` or `.h5` file and leave `simulate` out). `[bank]` is the template family scanned in every disc,
in the three default morphologies; any section of the single-disc configuration (`[grid]`, `[frank]`,
`[limits]`, ...; `spiralbayes scan --print-config` lists them) applies to every disc, and a
`[disc.<section>]` table overrides it for one disc.
'''),
    code('''
import tempfile
from pathlib import Path

folder = Path(tempfile.mkdtemp(prefix="spiralbayes-survey-"))
n_r_p = 25 if FULL else 8
# reduced size: a smaller frank fit, no test 3 (the alternatives) and no per-disc figures
quick = "" if FULL else "[frank]\\nN = 100\\n[alternatives]\\nfit = false\\n[output]\\nplots = false\\n"
survey_file = folder / "survey.toml"
survey_file.write_text(f"""
[survey]
name = "two synthetic Taurus discs"
output = "survey-output"
scheduler = "serial"
posterior = "none"

[bank]
mass = [1.0, 3.0]
tau0 = [0.3]
beta = [10.0]
h_p = [0.07]
wavelength = 1.33e-3

[grid]
r_p_max = 0.5
n_r_p = {n_r_p}

{quick}
[[disc]]
name = "Disc A"
path = "data/disc_a.h5"
distance = 140.0
inc = 30.0
PA = 60.0
fit_geometry = false
simulate = {{ preset = "taurus", flux = 0.12, r_eff = 0.3, seed = 1 }}

[[disc]]
name = "Disc B"
path = "data/disc_b.h5"
distance = 160.0
inc = 45.0
PA = 120.0
fit_geometry = false
simulate = {{ preset = "taurus", flux = 0.08, r_eff = 0.4, seed = 2 }}
""")
'''),
    md('''
## 2. On a laptop

`scheduler = "serial"` runs the discs one after the other in this process; `"local"` (or `""`, the
default) starts a Dask LocalCluster with one single-threaded worker per core and runs the discs' tasks
in parallel.
'''),
    code('''
run = sb.run_survey(survey_file, progress=False)
print("failed discs:", run.failed or "none")
run.table["disc", "R_eff95_au", "excluded_ge3Mth", "excluded_ge1Mth", "verdict", "delta_bic"]
'''),
    md('''
The output folder holds the table (`survey_table.ecsv`, `survey_table.md`), the provenance of the run,
one page of every disc's limits (`figures/limits_grid.png`) and, under `discs/<name>/`, exactly what
`spiralbayes scan` and `spiralbayes limits` write for one disc. A rerun skips every stage whose inputs
did not change.
'''),
    code('''
sorted(str(p.relative_to(folder / "survey-output")) for p in (folder / "survey-output").glob("*"))
'''),
    md('''
## 3. On a cluster (shown, not run here)

On a SLURM or PBS cluster (`pip install "spiralbayes[cluster]"`), set the scheduler and the batch
options in the survey file; the survey starts the batch jobs, runs the discs' tasks on their workers and
releases the jobs at the end:

```toml
[survey]
scheduler = "slurm"       # or "pbs"
[cluster]                 # keyword arguments of dask_jobqueue.SLURMCluster / PBSCluster
jobs = 8
cores = 16                # 16 worker processes x 1 thread per job
memory = "64GB"
walltime = "04:00:00"
queue = "compute"
account = "disc-survey"
```

Or start a cluster yourself and pass its address (or a `distributed.Client`):

```python
from dask_jobqueue import SLURMCluster

cluster = SLURMCluster(cores=16, processes=16, memory="64GB", walltime="04:00:00")
cluster.scale(jobs=8)
run = sb.run_survey("survey.toml", scheduler=cluster.scheduler_address)
```

From the command line: `spiralbayes survey survey.toml --scheduler tcp://head-node:8786`. The survey
page of this site gives the measured costs and the MPI variant.
'''),
]

TUTORIALS["own_templates"] = [
    md('''
# Your own templates: from a FITS or FARGO3D run

The built-in templates come from a semi-analytic wake generator. If you have hydrodynamic simulations of
your own — a δ map (the brightness perturbation ΔI/⟨I⟩_φ over radius and azimuth) from your
radiative-transfer pipeline, or a FARGO3D output — turn them into templates and scan with them exactly
as with the built-in bank.
'''),
    code(SETUP),
    md('''
## 1. A δ map in FITS files

`sb.templates.read_fits_template` reads the layout of Stevenson et al. (2024): four FITS files sharing a
prefix — the δ map over (r, φ), the radial cell centres (in au, with the planet at `r_planet`), and the
azimuth centres (before and after the authors' shift). Here a map is written first, standing in for
your simulation's; with your own files, start at `read_fits_template`.
'''),
    code('''
import tempfile
from pathlib import Path

folder = Path(tempfile.mkdtemp(prefix="spiralbayes-templates-"))
stand_in = sb.make_template(mass=3.0, tau0=3.0, beta=10.0, h_p=0.07, wavelength=1.33e-3)
written = sb.templates.write_fits_template(stand_in, folder / "my_run", r_planet=50.0)
print([p.name for p in written])
'''),
    code('''
own = sb.templates.read_fits_template(folder / "my_run", r_planet=50.0, mass=3.0, tau0=3.0, beta=10.0, h_p=0.07,
                                      wavelength=1.33e-3, hand="R", name="my_run_R")
print(own.name, own.shape, f"peak delta {own.peak():.2f}")
sb.plotting.plot_template(own)
'''),
    md('''
The labels (mass, τ0, β, H/r) are yours to set: the scan reports them, and the limits group templates
into families by them. Spirals are handed; `mirror()` makes the other hand.

## 2. A bank of your own, and a scan

A `TemplateBank` holds any templates; save it once (`bank.save("my_bank.h5")`,
`sb.TemplateBank.load(...)`) and give it to `sb.scan` like the built-in one.
'''),
    code('''
bank = sb.TemplateBank([own, own.mirror()])
bank.save(folder / "my_bank.h5")
bank = sb.TemplateBank.load(folder / "my_bank.h5")

geometry = sb.DiscGeometry(inc=30.0, PA=60.0)
vis = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0, tau_ref=3.0), geometry, own,
                              r_p=0.4, phi_p=np.radians(200.0), seed=7)
disc = sb.fit_axisymmetric(vis, geometry, progress=False, **FRANK)
result = sb.scan(vis, disc, bank, r_p=np.linspace(0.2, 0.6, 17 if FULL else 9), distance=140.0, progress=False)
print(sb.detect(result).summary())
'''),
    md('''
## 3. From a FARGO3D run (shown, not run here)

`sb.templates.read_fargo3d` reads a 2-D FARGO3D output directory (merged or per-rank binary fields,
`variables.par`, the domain files and `planet0.dat`), rotates the planet to φ = 0 and applies the S22
radiative transfer for a given dust optical depth at the planet:

```python
template = sb.templates.read_fargo3d("my_run/outputs", output=40, tau0=0.3, fluid="dust1",
                                     wavelength=1.33e-3, beta=0.0)
```

`fluid="gas"` uses the gas density when the run has no dust (dust follows gas for Stokes numbers
≲ 0.1). The result is a `SpiralTemplate` like the one above: mirror it, put it in a bank, scan.
'''),
]


def main():
    for name, cells in TUTORIALS.items():
        nb = new_notebook(cells=cells, metadata={"kernelspec": {"name": "python3", "display_name": "Python 3",
                                                               "language": "python"}})
        nbformat.write(nb, HERE / f"{name}.ipynb")


if __name__ == "__main__":
    main()
