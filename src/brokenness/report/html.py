"""One self-contained HTML page for a set of results (``brokenness report --html``).

The page holds everything inline (pictures as ``data:`` URIs, the style and a few lines of
script), so it opens offline, can be mailed or archived as one file, and loads nothing
from the network. It has

* the summary: one row per result (its labels, status, degree, partitions, largest share,
  unassigned share, Psi of the aligned and the repaired map, method, time), sortable by
  any column (click its header, again for descending; numbers sort numerically, empty
  cells last). The page also sorts on load when its address ends in ``#sort=COLUMN`` or
  ``#sort=COLUMN:desc`` (``#click=COLUMN,COLUMN`` clicks those headers in turn);
* the grouped table of ``brokenness compare`` and its figure;
* per result: its overlay picture, its partitions (size, transform in cells and, when
  known, in metres, conventions stated) and its parameters and inputs.

Once loaded, the page sets ``data-images-loaded`` / ``data-images-total`` on ``<body>``
(pictures that decoded), which a headless browser test reads back.
"""

from __future__ import annotations

import base64
import html
import io
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .collect import ResultEntry, collect_results, label_names
from .results import ResultRecord, atomic_write, load_results

__all__ = ["render_html", "write_html"]

_STYLE = """
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { padding: 2px 8px; border-bottom: 1px solid #ddd; text-align: right; }
th { background: #f3f3f3; position: sticky; top: 0; }
th.sortable { cursor: pointer; user-select: none; }
th.sorted-asc::after { content: " \\25B2"; } th.sorted-desc::after { content: " \\25BC"; }
td.text, th.text { text-align: left; }
tr.error td { color: #a00; } tr.not-measured td { color: #850; }
img { max-width: min(100%, 1000px); height: auto; border: 1px solid #eee; }
section.result { border-top: 2px solid #ccc; margin-top: 2em; }
pre { background: #f7f7f7; padding: 0.5em; overflow-x: auto; font-size: 12px; }
.note { color: #555; font-size: 0.9em; }
"""

_SCRIPT = """
(function () {
  function key(cell) {
    var v = cell.getAttribute('data-value');
    if (v === null) { v = cell.textContent; }
    v = v.trim();
    if (v === '' || v === '-') { return null; }
    var n = Number(v);
    return isNaN(n) ? v.toLowerCase() : n;
  }
  function sortTable(table, col, desc) {
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a.cells[col]), y = key(b.cells[col]);
      if (x === null && y === null) { return 0; }
      if (x === null) { return 1; }
      if (y === null) { return -1; }
      if (typeof x !== typeof y) { x = String(x); y = String(y); }
      var c = x < y ? -1 : (x > y ? 1 : 0);
      return desc ? -c : c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
    var heads = table.tHead.rows[0].cells;
    for (var i = 0; i < heads.length; i++) {
      heads[i].classList.remove('sorted-asc', 'sorted-desc');
    }
    heads[col].classList.add(desc ? 'sorted-desc' : 'sorted-asc');
    table.setAttribute('data-sorted', heads[col].getAttribute('data-column') +
                       (desc ? ':desc' : ':asc'));
  }
  document.querySelectorAll('table.sortable').forEach(function (table) {
    var heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, col) {
      th.classList.add('sortable');
      th.addEventListener('click', function () {
        sortTable(table, col, th.classList.contains('sorted-asc'));
      });
    });
  });
  function sortFromAddress() {
    // #sort=COLUMN[:desc] sorts the summary; #click=COLUMN[,COLUMN...] clicks headers
    var m = /^#(sort|click)=(.+?)(:desc)?$/.exec(decodeURIComponent(location.hash));
    if (!m) { return; }
    var table = document.getElementById('summary');
    var heads = table.tHead.rows[0].cells;
    m[2].split(',').forEach(function (name) {
      for (var i = 0; i < heads.length; i++) {
        if (heads[i].getAttribute('data-column') !== name) { continue; }
        if (m[1] === 'click') { heads[i].click(); } else { sortTable(table, i, !!m[3]); }
      }
    });
  }
  sortFromAddress();
  window.addEventListener('hashchange', sortFromAddress);
  window.addEventListener('load', function () {
    var images = document.images, ok = 0;
    for (var i = 0; i < images.length; i++) {
      if (images[i].complete && images[i].naturalWidth > 0) { ok++; }
    }
    document.body.setAttribute('data-images-loaded', String(ok));
    document.body.setAttribute('data-images-total', String(images.length));
  });
})();
"""


def _e(value: Any) -> str:
    return html.escape("" if value is None else str(value), quote=True)


def _num(value: Any, fmt: str = ".3f") -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return format(value, fmt)
    return str(value)


def _png(data: bytes, alt: str) -> str:
    encoded = base64.b64encode(data).decode("ascii")
    return f'<img alt="{_e(alt)}" src="data:image/png;base64,{encoded}">'


def _anchor(i: int) -> str:
    return f"result-{i}"


def _summary_rows(
    entries: Sequence[ResultEntry], records: Sequence[ResultRecord | None]
) -> tuple[list[str], list[str]]:
    labels = label_names(entries)
    columns = [
        ("result", "text"),
        *((f"label:{n}", "text") for n in labels),
        ("status", "text"),
        ("degree", ""),
        ("partitions", ""),
        ("largest", ""),
        ("unassigned", ""),
        ("psi_map", ""),
        ("psi_repaired", ""),
        ("method", "text"),
        ("seconds", ""),
    ]
    heads = []
    for name, kind in columns:
        shown = name.split(":", 1)[-1].replace("psi_", "\N{GREEK CAPITAL LETTER PSI} ")
        heads.append(f'<th class="{kind}" data-column="{_e(name)}">{_e(shown)}</th>')
    rows = []
    for i, (e, rec) in enumerate(zip(entries, records, strict=True)):
        stats = rec.stats if rec is not None else {}
        timings = (rec.info.get("timings") or {}) if rec is not None else {}
        if e.failed:
            status, css = "error", "error"
        elif not e.measured:
            status, css = "not measured", "not-measured"
        else:
            status, css = "done", ""
        name = f'<a href="#{_anchor(i)}">{_e(e.path.name)}</a>'
        cells = [f'<td class="text" data-value="{_e(e.path.name)}">{name}</td>']
        cells += [f'<td class="text">{_e(e.labels.get(n, ""))}</td>' for n in labels]
        cells.append(f'<td class="text">{_e(status)}</td>')
        values = [
            e.degree,
            len(e.partition_fractions) if not e.failed else None,
            e.largest_fraction,
            stats.get("unassigned_fraction"),
            e.psi_map,
            e.psi_repaired,
        ]
        cells += [f"<td>{_e(_num(v))}</td>" for v in values]
        cells.append(f'<td class="text">{_e(e.method or "")}</td>')
        seconds = timings.get("total_seconds", timings.get("compute_seconds"))
        cells.append(f"<td>{_e(_num(seconds, '.2f'))}</td>")
        rows.append(f'<tr class="{css}">' + "".join(cells) + "</tr>")
    return heads, rows


def _partitions_table(stats: dict[str, Any]) -> str:
    parts = stats.get("partitions") or []
    if not parts:
        return "<p>No partition (the degree was not measured).</p>"
    metres = any((p.get("transform") or {}).get("world") for p in parts)
    head = ["#", "cells", "share", "rot°", "shift (cells)"]
    head += ["world rot°", "shift (m)"] if metres else []
    head += ["off°", "off (m)" if metres else "off (cells)", "conf"]
    out = ['<table class="sortable partitions"><thead><tr>']
    out += [f'<th data-column="{_e(h)}">{_e(h)}</th>' for h in head]
    out.append("</tr></thead><tbody>")
    for p in parts:
        t = p.get("transform") or {}
        tx, ty = (t.get("translation_cells") or [None, None])[:2]
        row = [p.get("index"), p.get("cells"), f"{100 * float(p.get('fraction', 0)):.1f}%"]
        row += [_num(t.get("rotation_deg"), ".2f"), f"{_num(tx, '.1f')}, {_num(ty, '.1f')}"]
        if metres:
            w = t.get("world") or {}
            wx, wy = (w.get("translation_m") or [None, None])[:2]
            row += [_num(w.get("rotation_deg"), ".2f"), f"{_num(wx, '.2f')}, {_num(wy, '.2f')}"]
        off = p.get("displacement_m") if metres else p.get("displacement_cells")
        row += [
            _num(p.get("rotation_offset_deg"), ".2f"),
            _num(off, ".2f"),
            _num(p.get("confidence"), ".2f"),
        ]
        out.append("<tr>" + "".join(f"<td>{_e(v)}</td>" for v in row) + "</tr>")
    out.append("</tbody></table>")
    out.append(
        '<p class="note">rot° / shift (cells): map cells onto reference cells, y down, '
        "+ = clockwise on screen; world rot° / shift (m): the ROS world frames, y up, + = "
        "counter-clockwise; off: rotation and displacement relative to partition 0.</p>"
    )
    return "".join(out)


def _result_section(i: int, e: ResultEntry, rec: ResultRecord | None) -> str:
    out = [f'<section class="result" id="{_anchor(i)}"><h2>{_e(e.path.name)}</h2>']
    if e.labels:
        labels = ", ".join(f"{k} = {v}" for k, v in e.labels.items())
        out.append(f"<p>labels: {_e(labels)}</p>")
    if rec is None:
        out.append(f'<p class="error">failed: {_e(e.error)}</p></section>')
        return "".join(out)
    stats = rec.stats
    degree = stats.get("degree") if rec.measured else "not measured"
    reason = f" ({stats.get('reason')})" if not rec.measured and stats.get("reason") else ""
    out.append(f"<p>degree of brokenness: <b>{_e(degree)}</b>{_e(reason)}</p>")
    if rec.overlay_png:
        out.append(_png(rec.overlay_png, f"overlay of {e.path.name}"))
    out.append(_partitions_table(stats))
    inputs = rec.info.get("inputs") or {}
    shown = {
        "method": rec.info.get("method"),
        "parameters": rec.info.get("parameters"),
        "inputs": inputs,
        "version": rec.info.get("version"),
        "created": rec.info.get("created"),
    }
    out.append("<details><summary>parameters and inputs</summary><pre>")
    out.append(_e(json.dumps(shown, indent=2, sort_keys=True, default=str)))
    out.append("</pre></details></section>")
    return "".join(out)


def _figure_png(entries: Sequence[ResultEntry]) -> bytes | None:
    from ..errors import ParameterError
    from .plots import comparison_figure

    try:
        fig = comparison_figure(entries)
    except ParameterError:
        return None
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    return buf.getvalue()


def _group_html(entries: Sequence[ResultEntry]) -> str:
    from .tables import group_table

    table = group_table(entries)
    heads = "".join(
        f'<th class="{"text" if c in table.group_by else ""}" data-column="{_e(c)}">{_e(c)}</th>'
        for c in table.columns
    )
    rows = []
    for rec in table.records():
        cells = []
        for c in table.columns:
            kind = "text" if c in table.group_by else ""
            cells.append(f'<td class="{kind}">{_e(_num(rec[c]))}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return (
        f'<table class="sortable" id="groups"><thead><tr>{heads}</tr></thead>'
        f"<tbody>{''.join(rows)}</tbody></table>"
    )


def render_html(
    paths: Sequence[str | os.PathLike[str]], *, title: str = "brokenness results"
) -> str:
    """The report page of the result zips (and batch folders) ``paths``, as text.

    Raises
    ------
    ResultFileError
        For a missing or damaged result file (as :func:`collect_results`).
    """
    entries = collect_results(paths)
    records = [None if e.failed else load_results(e.path) for e in entries]
    heads, rows = _summary_rows(entries, records)
    failed = sum(e.failed for e in entries)
    not_measured = sum(1 for e in entries if not e.failed and not e.measured)
    n = len(entries)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{_e(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f"<p>{n} result{'' if n == 1 else 's'}: {n - failed - not_measured} measured, "
        f"{not_measured} not measured, {failed} failed. Click a column's header to sort.</p>",
        '<table class="sortable" id="summary"><thead><tr>',
        "".join(heads),
        "</tr></thead><tbody>",
        "".join(rows),
        "</tbody></table>",
        "<h2>By group</h2>",
        _group_html(entries),
    ]
    figure = _figure_png(entries)
    if figure is not None:
        parts.append(_png(figure, "comparison plots"))
    parts += [
        _result_section(i, e, r) for i, (e, r) in enumerate(zip(entries, records, strict=True))
    ]
    parts.append(f"<script>{_SCRIPT}</script></body></html>")
    return "\n".join(parts) + "\n"


def write_html(
    paths: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    title: str = "brokenness results",
) -> Path:
    """Write :func:`render_html` to ``out`` (atomically)."""
    p = Path(out)
    atomic_write(p, render_html(paths, title=title).encode("utf-8"))
    return p
