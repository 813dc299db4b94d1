"""Inference: χ² and BIC, the grid scan and its verdict, the spiral likelihood and its posterior.

* :mod:`.statistics` — χ², the Gaussian likelihood, ΔBIC;
* :mod:`.scan_engine`, :mod:`.scan` — Δχ² of every template at every planet position;
* :mod:`.detection` — the paper's tests 1 and 2 on a scan (:func:`detect`);
* :mod:`.limits`, :mod:`.families`, :mod:`.limits_table`, :mod:`.calibration` — exclusion limits,
  the limiting mass per template family, the paper's Table 3, planted-planet calibration;
* :mod:`.injection`, :mod:`.completeness` — injection–recovery without re-scanning, M_det;
* :mod:`.forecast` — expected Δχ², detection probability and time on source for a set-up;
* :mod:`.tables`, :mod:`.likelihood` — the fast spiral likelihood for MCMC;
* :mod:`.priors`, :mod:`.evidence`, :mod:`.sampler`, :mod:`.diagnostics`, :mod:`.results` — the
  emcee posterior with templates as a discrete choice.
"""
