"""Reports: figures and tables of the paper's section 4, and one self-contained HTML file.

:func:`build_report` turns any terracone result (the JSON of predict, learn, evaluate
or sites, a prediction table or batch directory read by
:func:`terracone.result.read_results`, a reproduce directory, or a directory of such JSON
files: the table in ``docs/report.md``) into one HTML file that loads nothing from any host.
Figures: :mod:`terracone.report.figures`; tables: :mod:`terracone.report.tables`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from terracone.io.jsonkeys import read_json
from terracone.report.html import (
    batch_document,
    evaluate_document,
    learn_document,
    predict_document,
    render_document,
)
from terracone.result import check_schema, read_results, to_document

__all__ = ["build_report", "load_document", "result_kind"]


def result_kind(doc: Any) -> str:
    """Kind of a terracone JSON result: "predict", "learn", "evaluate", "reproduce", "sites",
    "mobility" or "mobility-map" (a P(GO) map's ``mobility.json``).

    A document with a ``schema`` key is read by it (``terracone.prediction/1``
    is a prediction; another schema or version is refused with the reason);
    older documents without it are told apart by their keys.
    """
    if not isinstance(doc, dict):
        raise ValueError("not a terracone result: expected a JSON object")
    if doc.get("command") == "mobility":
        return "mobility-map" if doc.get("schema") == "terracone.mobility-map/1" else "mobility"
    if "schema" in doc or "schema_version" in doc:
        check_schema(doc)
        return "predict"
    cmd = doc.get("command")
    if doc.get("kind") == "terracone-reproduce":
        return "reproduce"
    if cmd in ("predict", "learn", "evaluate", "sites"):
        return str(cmd)
    if "profiles" in doc:
        return "predict"
    if "datasets" in doc and "kc" in doc:
        return "learn"
    if isinstance(doc.get("plates"), list) and all(
        isinstance(r, dict) and "prediction" in r and "test" in r for r in doc["plates"]
    ):
        return "evaluate"
    raise ValueError(
        "not a terracone result: expected the JSON of predict, learn or evaluate "
        "(keys 'profiles', 'datasets' or 'plates')"
    )


def load_document(
    results_path: str | Path, *, map_by: str = "n"
) -> tuple[dict[str, Any], Path | None]:
    """The report document for a results file or directory, and its base directory.

    ``map_by``: the parameter that colours the map of located profiles.
    """
    p = Path(results_path)
    if not p.exists():
        raise ValueError(f"{p}: no such file or directory")
    if p.is_dir():
        if (p / "map.json").exists():  # a terracone map directory (issue 22)
            from terracone.report.maps import map_document

            return map_document(p), p
        if (p / "reproduce.json").exists():
            doc = read_json(p / "reproduce.json")
            if result_kind(doc) != "reproduce":
                raise ValueError(f"{p / 'reproduce.json'}: not written by terracone reproduce")
            return doc["document"], p
        if any(p.glob("part-*.parquet")):
            return batch_document(read_results(p), p, map_by=map_by), p
        docs = []
        for f in sorted(p.glob("*.json")):
            try:
                d = read_json(f)
                kind = result_kind(d)
            except ValueError:
                continue
            if kind != "reproduce":
                docs.append((f, kind, d))
        if not docs:
            raise ValueError(
                f"{p}: no terracone results found (expected reproduce.json, part-*.parquet "
                "or JSON of predict, learn or evaluate)"
            )
        if len(docs) == 1:
            f, kind, d = docs[0]
            return _document(kind, d, str(f), map_by), p
        sections = []
        for f, kind, d in docs:
            sub = _document(kind, d, str(f), map_by)
            for s in sub["sections"]:
                sections.append(
                    {**s, "id": f"{f.stem}-{s['id']}", "heading": f"{f.name}: {s['heading']}"}
                )
        return {
            "title": "terracone report",
            "subtitle": f"{len(docs)} results in {p}",
            "meta": {"results": str(p)},
            "sections": sections,
        }, p
    if p.suffix.lower() in (".parquet", ".pq"):
        return batch_document(read_results(p), p, map_by=map_by), p.parent
    doc = read_json(p)
    try:
        kind = result_kind(doc)
    except ValueError as exc:
        raise ValueError(f"file {p}: {exc}") from exc
    if kind == "reproduce":
        return doc["document"], p.parent
    return _document(kind, doc, str(p), map_by), p.parent


def _prediction_document(source: str) -> dict[str, Any]:
    """A prediction JSON document read by :func:`terracone.result.read_results` (SI) and
    written again in its own units by the one JSON writer, :func:`terracone.result.to_document`."""
    results = read_results(source)
    head = dict(results.header)
    units = head.pop("units", None) or results.settings.get("units") or "si"
    command, input = head.pop("command", "predict"), head.pop("input", None)
    settings = results.settings or None
    return to_document(
        results, units, command=command, input=input, settings=settings, samples=False, **head
    )


def _document(kind: str, doc: dict[str, Any], source: str, map_by: str = "n") -> dict[str, Any]:
    if kind == "predict":
        return predict_document(_prediction_document(source), source=source, map_by=map_by)
    if kind == "learn":
        return learn_document(doc, source=source)
    if kind == "evaluate":
        return evaluate_document(doc, source=source)
    if kind == "sites":
        from terracone.report.sites import sites_document

        return sites_document(doc, source=source)
    if kind == "mobility":
        from terracone.report.mobility import mobility_document

        return mobility_document(doc, source=source)
    if kind == "mobility-map":
        from terracone.report.mobility import go_map_document

        return go_map_document(doc, Path(source).parent)
    raise ValueError(f"unknown result kind {kind!r}")  # pragma: no cover


def build_report(results_path: str | Path, out_html: str | Path, *, map_by: str = "n") -> Path:
    """Write one self-contained HTML report of a terracone result.

    Parameters
    ----------
    results_path : str or Path
        JSON of ``predict``, ``learn`` or ``evaluate``; or the output
        directory of ``batch`` or of ``reproduce``; or a directory of such
        JSON files.
    out_html : str or Path
        The HTML file to write (its folder is created).
    map_by : {"n", "kc", "kphi", "cc", "phic", "rmsd", "r2"}
        The parameter that colours the map of located profiles (section
        ``map``, drawn when profiles carry lon/lat).

    Returns
    -------
    Path
        ``out_html``.

    Raises
    ------
    ValueError
        When the results cannot be read or are not terracone results.
    """
    document, base = load_document(results_path, map_by=map_by)
    text = render_document(document, base)
    out = Path(out_html)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    return out
