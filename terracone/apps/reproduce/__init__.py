"""Re-create the paper's two case studies on synthetic data: the computation.

SYNTHETIC DATA: generated from the published parameters (Tables 4-1 and 4-3)
with the noise model :data:`NOISE_MODEL`, then learned, predicted and
evaluated; ``docs/report.md`` explains the data.  :func:`reproduce` writes the
synthetic inputs (``data/``) and the results (``results/``) and returns a
:class:`Reproduction`; :mod:`terracone.report.reproduce` draws the figures,
tables and the report beside the published tables.

* :mod:`~terracone.apps.reproduce.paper`: the published Tables 4-1 to 4-4 (package data);
* :mod:`~terracone.apps.reproduce.cases`: the two case studies as data, their synthetic data;
* :mod:`~terracone.apps.reproduce.fits`: learning, prediction, posteriors, evaluation;
* :mod:`~terracone.apps.reproduce.pool`: anything with a ``map`` (as in emcee);
* :mod:`~terracone.apps.reproduce.run`: :func:`reproduce`, its output folder and files.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-1 to 4-4, Figures 2-1, 4-1 to 4-10.
"""

from terracone.apps.reproduce.cases import KRC_FORCE_LIMIT, NOISE_MODEL, WONG_LETE, Case
from terracone.apps.reproduce.run import Reproduction, reproduce

__all__ = ["Case", "KRC_FORCE_LIMIT", "NOISE_MODEL", "Reproduction", "WONG_LETE", "reproduce"]
