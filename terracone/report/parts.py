"""The parts of a report document: text, lists, key-value pairs, figures, tables.

A document (:func:`terracone.report.html.render_document`) is a list of
sections, each a list of these parts; the HTML page and the figures' PNG
files are drawn from them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from terracone.report.figures import png_bytes
from terracone.report.tables import Table

__all__ = ["text_part", "list_part", "kv_part", "figure_part", "table_part"]


def text_part(text: str) -> dict[str, Any]:
    """A paragraph."""
    return {"type": "text", "text": text}


def list_part(items: Sequence[str]) -> dict[str, Any]:
    """A bulleted list."""
    return {"type": "list", "items": list(items)}


def kv_part(pairs: Mapping[str, Any]) -> dict[str, Any]:
    """A two-column list of names and values."""
    return {"type": "kv", "pairs": {str(k): v for k, v in pairs.items()}}


def figure_part(
    fig: Any, caption: str, *, alt: str | None = None, wide: bool = False
) -> dict[str, Any]:
    """A figure part with its PNG in memory (``png_bytes``).

    ``wide``: on narrow screens (below 640 px) the image keeps 720 px and
    scrolls sideways inside its own box instead of shrinking (small
    multiples stay legible on a phone; the page itself never scrolls
    sideways).
    """
    return {
        "type": "figure",
        "png_bytes": png_bytes(fig),
        "caption": caption,
        "alt": alt or caption.split(".")[0],
        "wide": wide,
    }


def table_part(
    table: Table,
    *,
    max_rows: int | None = None,
    sortable: bool | None = None,
    tall: bool = False,
) -> dict[str, Any]:
    """A table part.

    ``sortable``: column headings sort the rows (None: when it has 3 rows or
    more); ``tall``: the table scrolls inside a box of at most 70% of the
    window height, with its heading row kept in view.
    """
    return {
        "type": "table",
        "table": table,
        "max_rows": max_rows,
        "sortable": sortable,
        "tall": tall,
    }
