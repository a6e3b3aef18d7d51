"""The ``terracone`` command line.

Every sub-command reads files in terracone's formats (units in the column
names) or instrument exports, computes in SI, and prints a table, or JSON
with ``--json`` (a stable contract).  Bad input ends with one message naming
the file, profile, row and column, and a non-zero exit; never a traceback.

One module per group of commands (:mod:`.forward`, :mod:`.fit`,
:mod:`.bevameter`, :mod:`.library`, :mod:`.export`, :mod:`.batch`, :mod:`.report`);
:mod:`.common` holds the shared options and parsing, :mod:`.main` the group.
"""

from terracone.cli.main import cli, main

__all__ = ["cli", "main"]
