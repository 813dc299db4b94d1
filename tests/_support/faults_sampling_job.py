"""The small posterior run that tests/test_faults_sampling.py kills and resumes (also run in-process).

    python -m tests._support.faults_sampling_job OUT_DIR
"""

import sys

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.inference.posterior.priors import Priors
from spiralbayes.inference.posterior.sampler import sample_posterior
from tests._support.posterior_setup import TRUE_GEOMETRY, build_weak_observation, profile, weak_template

N_STEPS = 60
FLUSH = 10


def run(out_dir):
    vis = build_weak_observation()
    model = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=60)
    template = weak_template()
    priors = Priors.default(model, r_p=(0.3, 0.4))
    return sample_posterior(vis, model, [template, template.mirror()], priors=priors, run_name="job",
                            chains_dir=out_dir,
                            n_walkers=12, n_steps=N_STEPS, flush_every=FLUSH, mcmc_templates=[template.name],
                            convergence="ignore", evidence_draws=100, progress=False, seed=7,
                            likelihood_kwargs={"rp_tolerance": 0.05})


if __name__ == "__main__":
    run(sys.argv[1])
