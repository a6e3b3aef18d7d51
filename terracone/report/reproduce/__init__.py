"""The report of the paper's case studies re-created on synthetic data (``terracone reproduce``).

:func:`reproduce_report` runs :func:`terracone.apps.reproduce.reproduce` (the
computation: synthetic data, learning, prediction, posteriors, evaluation) and
draws its figures, tables and HTML report beside the published tables;
:func:`write_reproduce_report` draws them from a
:class:`~terracone.apps.reproduce.run.Reproduction` already computed.

* :mod:`~terracone.report.reproduce.document`: the run's report, ``report.html``, ``reproduce.json``;
* :mod:`~terracone.report.reproduce.builders`: one builder per kind of table or figure;
* :mod:`~terracone.report.reproduce.texts`: the sections and the words of each part;
* :mod:`~terracone.report.reproduce.reading`: ours beside the paper, in plain language.
"""

from terracone.report.reproduce.document import (
    ReproduceSummary,
    reproduce_report,
    write_reproduce_report,
)

__all__ = ["ReproduceSummary", "reproduce_report", "write_reproduce_report"]
