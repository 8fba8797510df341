"""The fleet's summary files: ``fleet.csv`` (one row per recording and joint) and ``index.html``.

Both are written last and at once (``staged_files``), and ``run.json`` with them: the
recordings' own report folders, each complete or absent, are written as they finish.
"""
from __future__ import annotations

import csv
from html import escape
from pathlib import Path

from .html import _num, _page
from .output import MARKER, staged_files, write_json
from .summary import SIGNAL_ORDER, none_named

CSV_NAME = "fleet.csv"


def _nrmse(row: dict, when: str) -> str:
    return ", ".join(f"{s} {_num(row[f'nrmse_{when}_{s}'])}" for s in SIGNAL_ORDER if row[f"nrmse_{when}_{s}"] != "")


def fleet_page(source: str, rows: list[dict], run: dict) -> str:
    """``index.html`` of a fleet: a line of counts and one table row per recording and joint."""
    failed = sum(r["status"] == "failed" for r in rows)
    heads = ["recording", "joint", "missing, in the order found", "held-out NRMSE, base model",
             "held-out NRMSE, final model", "wall time [s]", "status"]
    body = [f"<h1>mjjoint diagnose: {escape(source)}</h1>",
            f'<p class="verdict{" found" if failed else ""}">{escape(run["summary"])}</p>',
            "<table><tr>" + "".join(f"<th>{escape(h)}</th>" for h in heads) + "</tr>"]
    for r in rows:
        name = escape(r["recording"])
        if r["status"] == "failed":
            cells = [name, "", "", "", "", _seconds(r), f"failed: {escape(r['error'])}"]
        else:
            missing = ", ".join(f"<code>{escape(e)}</code>" for e in r["missing"].split(";") if e)
            cells = [f'<a href="{escape(r["report"])}">{name}</a>', str(r["joint"]),
                     missing or none_named(r["explained"]), _nrmse(r, "before"), _nrmse(r, "after"), _seconds(r),
                     "ok (earlier run)" if r["reused"] else "ok"]
        body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    body += ["</table>", f'<p class="muted">Rows: <code>{CSV_NAME}</code>; each recording\'s report in its '
             "own folder. Reused reports come from an earlier run with the same inputs and options.</p>"]
    return _page(f"mjjoint diagnose: {source}", body)


def _seconds(row: dict) -> str:
    return f"{float(row['seconds']):.1f}"


def write_fleet(folder: Path, fields: tuple[str, ...], rows: list[dict], source: str, run: dict) -> None:
    """``fleet.csv``, ``index.html`` and ``run.json`` in ``folder``, all replaced together."""
    finals = [folder / CSV_NAME, folder / "index.html", folder / MARKER]
    with staged_files(finals) as partial:
        with open(partial[finals[0]], "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
            writer.writeheader()
            writer.writerows(rows)
        partial[finals[1]].write_text(fleet_page(source, rows, run), encoding="utf-8")
        write_json(partial[finals[2]], run)
