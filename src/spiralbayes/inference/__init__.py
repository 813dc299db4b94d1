"""Inference: χ² and BIC, the grid scan and its verdict, the spiral likelihood and its posterior.

* :mod:`.statistics` — χ², the Gaussian likelihood, ΔBIC;
* :mod:`.scan_engine`, :mod:`.scan` — Δχ² of every template at every planet position;
* :mod:`.detection` — the paper's tests 1 and 2 on a scan (:func:`detect`);
* :mod:`.tables`, :mod:`.likelihood` — the fast spiral likelihood for MCMC;
* :mod:`.priors`, :mod:`.evidence`, :mod:`.sampler`, :mod:`.diagnostics`, :mod:`.results` — the
  emcee posterior with templates as a discrete choice.
"""
