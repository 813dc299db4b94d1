# %% [markdown]
# # Posterior of a planet-driven spiral: data → frank → scan → posterior → corner plot
#
# A notebook-style script (cells marked `# %%`; open it in VS Code / Jupytext, or run it with
# `python examples/posterior_notebook.py`). It simulates an observation with a planted planet so
# that it runs anywhere; replace the first cell by `load_visibilities("my_disc.npz")` for real data.
#
# Runtime on 2 cores: a few minutes (the frank fit and the scan of two templates take a minute or
# two; the posterior of the best template with 32 walkers a few more).

# %%
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # pin BLAS threads (emcee #199)

from pathlib import Path

import numpy as np

from spiralbayes.axisymmetric import fit_axisymmetric
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.posterior import Priors
from spiralbayes.inference.posterior import SamplingSettings, sample_posterior
from spiralbayes.inference.scan import scan
from spiralbayes.simulate import DiscModel, simulate_observation
from spiralbayes.templates import make_template

OUT = Path(os.environ.get("SPIRALBAYES_EXAMPLE_OUT", "posterior_example"))
OUT.mkdir(exist_ok=True)

# %% A synthetic observation: the paper's fiducial set-up, a 1 M_th planet at r_p = 0.3", phi_p = 2 rad
truth = {"r_p": 0.3, "phi_p": 2.0, "inc": 30.0, "PA": 60.0, "dRA": 0.0, "dDec": 0.0}
planet = make_template(1.0, 0.3, 0.0, "R")
geometry = DiscGeometry(truth["inc"], truth["PA"], truth["dRA"], truth["dDec"])
vis = simulate_observation("fiducial", DiscModel(), geometry, planet, r_p=truth["r_p"], phi_p=truth["phi_p"],
                           seed=1, sensitivity=10e-6)

# %% frank fit of the axisymmetric profile (geometry fitted too; the nonparametric fitter is the
# more accurate one for discs with rings and edges)
axisym = fit_axisymmetric(vis, fit_geometry="nonparametric")
print(axisym.geometry)

# %% Grid scan over the planet position for the true template and its mirror image
templates = [planet, planet.mirror()]
result_scan = scan(vis, axisym, templates, r_p=np.linspace(0.05, 0.6, 23))
print(result_scan.best)

# %% Posterior: r_p, phi_p, the amplitude A and the geometry nuisances, the frank profile integrated
# out; "no planet" competes with every template (weighted by their evidences)
priors = Priors.default(axisym, r_p=(0.05, 0.6), widths={"inc": 3.0, "PA": 3.0, "dRA": 0.02, "dDec": 0.02})
sampling = SamplingSettings(run_name="example", processes=2)  # every [sample] option, with its default
post = sample_posterior(vis, axisym, templates, scan_result=result_scan, priors=priors, settings=sampling,
                        chains_dir=OUT / "chains")
print(post.verdict)
print("P(planet | data) =", post.p_planet, "ln B =", post.ln_bayes_factor)
print(post.template_probabilities, "P(R | planet) =", post.p_right_handed)
print(post.summary())

# %% Corner plot with the truth, traces, template probabilities
from spiralbayes.plotting import plot_corner, plot_template_probabilities, plot_trace  # noqa: E402

plot_corner(post, truths={**truth, "A": 1.0}, distance=140.0).savefig(OUT / "posterior_corner.png", dpi=110)

plot_trace(post).savefig(OUT / "posterior_trace.png", dpi=90)
plot_template_probabilities(post).savefig(OUT / "posterior_templates.png", dpi=90)

# %% The frank profile is integrated out at every sampled geometry, so a fit made at a slightly wrong
# geometry does not bias the posterior. To look at frank's own fit (with its power-spectrum
# iterations) at the posterior geometry:
#     from spiralbayes.inference.posterior import refit_axisymmetric
#     refit = refit_axisymmetric(vis, axisym, post)

# %% arviz: R-hat and ESS (walkers as chains — emcee walkers are not independent, read with care)
idata = post.to_inference_data()
print(post.best.diagnostics["tau"], post.best.diagnostics["arviz"])
