"""The library as a prior (issue 32): stored calibrations weighed by the CI.

A :class:`~terracone.inverse.problem.Problem` with a ``library``
(:class:`~terracone.inverse.problem.LibraryPrior`) names candidate
calibrations.  For each candidate, its held problem fixes phic, cc, kc/kphi
and the pressure law, and leaves kphi and n free:

* :mod:`.evidence`: the noise model a profile shares between candidates, the
  evidence of the profile under each held problem (kphi integrated in closed
  form, n by quadrature, sigma marginalised) and the posterior it implies;
  the Laplace approximation beside it;
* :mod:`.check`: the posterior predictive check that says when no candidate
  explains the CI (outside the library);
* :mod:`.mixture`: candidates ranked by weight, the mixture's draws, medians,
  intervals and plate bands, and the prediction results built from them
  (what :func:`~terracone.inverse.predict.predict_many` returns for a library
  problem).

``docs/library.md`` (The library as a prior) states the model and its checks.
"""
