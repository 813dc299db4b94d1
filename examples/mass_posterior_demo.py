# %% [markdown]
# # How massive is the demo planet? The planet mass as a sampled parameter
#
# The demo's observation (`spiralbayes demo`: the fiducial set-up, a 1 M_th planet with τ0 = 3,
# β = 10, right-handed, at 50 au and 140 pc), frank, a scan of the family's bank templates, then the
# posterior with `mass="continuous"`: M_p is sampled (log-uniform on 0.1–3 M_th) with the planet's
# position and the disc geometry, and reported in M_th and M_Jup (M_* = 0.8 ± 0.08 M_sun).
# Run with `python examples/mass_posterior_demo.py` (4.3 minutes measured on 2 cores).

# %%
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pathlib import Path

import numpy as np

import spiralbayes as sb
from spiralbayes.pipeline.demo import DEMO_DISTANCE, DEMO_PLANET_AU

OUT = Path(os.environ.get("SPIRALBAYES_EXAMPLE_OUT", "mass_posterior_example"))
OUT.mkdir(exist_ok=True)

# %% The demo's observation, exactly as `spiralbayes demo` simulates it
geometry = sb.DiscGeometry(30.0, 60.0)
planet = sb.make_template(1.0, 3.0, 10.0, "R")
disc_model = sb.DiscModel(distance=DEMO_DISTANCE, r_ref=DEMO_PLANET_AU, tau_ref=3.0)
vis = sb.simulate_observation("fiducial", disc_model, geometry, planet, r_p=DEMO_PLANET_AU / DEMO_DISTANCE,
                              phi_p=0.0, seed=1)
disc = sb.fit_axisymmetric(vis, geometry, progress=False)

# %% The family's bank templates (one morphology, hand and H/r; four masses) and their scan
templates = [t for t in sb.compromise_bank().select(tau0=3.0, beta=10.0, h_p=0.07) if t.hand == "R"]
result = sb.scan(vis, disc, templates, geometry, distance=DEMO_DISTANCE, progress=False)

# %% The posterior with M_p sampled
post = sb.sample_posterior(vis, disc, templates, scan_result=result, mass="continuous",
                           mass_prior=sb.MassPrior(mstar=0.8, mstar_sigma=0.08), chains_dir=OUT / "chains",
                           settings=sb.SamplingSettings(run_name="demo_mass", n_walkers=20, max_steps=2000),
                           progress=False)
print(post.verdict)
mass = post.mass_posterior()
print("M_p [M_th]:", {k: round(v, 3) for k, v in mass["mth"].items()})
print("M_p [M_Jup]:", {k: round(v, 3) for k, v in mass["mjup"].items()})
# %% The template's mass alone (`lnM_p`, what the likelihood constrains) against the planet's (`M_p`, with
# the template-mismatch systematic, `MassPrior(systematic=...)`, default `MASS_SYSTEMATIC`)
draws = post.to_inference_data().posterior
levels = [2.5, 16, 50, 84, 97.5]
print("template mass [M_th], 2.5/16/50/84/97.5 %:", np.round(np.percentile(np.exp(draws["lnM_p"]), levels), 3))
print("planet mass [M_th], 2.5/16/50/84/97.5 %:", np.round(np.percentile(draws["M_p"], levels), 3))

# %% Corner plot with the truth (1 M_th; M_Jup for M_* = 0.8 M_sun and H/r = 0.07)
from spiralbayes.plotting import plot_corner  # noqa: E402

truth_mjup = sb.units.mth_to_mjup(1.0, DEMO_PLANET_AU, 0.8)
plot_corner(post, truths={"r_p": DEMO_PLANET_AU / DEMO_DISTANCE, "phi_p": 0.0, "inc": 30.0, "PA": 60.0,
                          "M_p": 1.0, "M_p_MJup": truth_mjup},
            distance=DEMO_DISTANCE).savefig(OUT / "mass_corner.png", dpi=100)
