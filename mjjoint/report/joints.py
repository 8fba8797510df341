"""The top-level page of a multi-joint ``fit`` or ``diagnose``: one row per joint, linking its report."""
from __future__ import annotations

from html import escape
from pathlib import Path

from .html import _num, _page
from .output import MARKER, write_json
from .summary import SIGNAL_ORDER, none_named


def _nrmse(values: dict[str, float]) -> str:
    return ", ".join(f"{s} {_num(values[s])}" for s in SIGNAL_ORDER if s in values)


def _rows(command: str, data: dict[str, dict]) -> list[str]:
    rows = []
    for j, d in data.items():
        link = f'<a href="joint{escape(j)}/index.html">joint {escape(j)}</a>'
        if command == "diagnose":
            missing = ", ".join(f"<code>{escape(e)}</code>" for e in d["missing"]) or none_named(d["explained"])
            cells = [missing, _nrmse(d["initial_fit"]["nrmse_heldout"]), _nrmse(d["final_fit"]["nrmse_heldout"])]
        else:
            effects = ", ".join(f"<code>{escape(e)}</code>" for e in d["structure"]["effects"]) or "minimal"
            cells = [effects, _nrmse(d["nrmse_test"])]
        rows.append(f"<tr><td>{link}</td>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    return rows


def joints_page(command: str, source: str, data: dict[str, dict], summary: dict | None, run: dict) -> str:
    """``index.html`` of a multi-joint run; ``summary``: the top-level diagnosis.json (diagnose only)."""
    body = [f"<h1>mjjoint {escape(command)}: {escape(source)}</h1>"]
    if summary is not None:
        found = " found" if summary["mismatch_in"] else ""
        body.append(f'<p class="verdict{found}">{escape(summary["verdict"])}</p>')
        heads = ["joint", "missing, in the order found", "held-out NRMSE, base model", "held-out NRMSE, final model"]
    else:
        heads = ["joint", "effects", "held-out NRMSE"]
    body += [("<p>Each joint was worked on alone, from its own columns; its report has the figures and "
              "numbers (see docs/multijoint.md for what the other joints' motion does to it).</p>"),
             "<table><tr>" + "".join(f"<th>{escape(h)}</th>" for h in heads) + "</tr>",
             *_rows(command, data), "</table>",
             "<h2>Files and budget</h2><ul>"
             + "".join(f"<li><code>{escape(f)}</code></li>" for f in run["files"])
             + f'</ul><p class="muted">{run["rollouts_full_length"]:g} full-length rollouts, '
               f'{run["seconds"]:.1f} s wall time.</p>']
    return _page(f"mjjoint {command}: {source}", body)


def write_joints_index(folder: Path, command: str, source: str, data: dict[str, dict], summary: dict | None,
                       run: dict) -> None:
    """``index.html`` and, last, ``run.json`` beside the joint folders already written."""
    index = folder / "index.html"
    run = {**run, "files": sorted([p.name + ("/" if p.is_dir() else "") for p in folder.iterdir()]
                                  + [index.name, MARKER])}
    index.write_text(joints_page(command, source, data, summary, run), encoding="utf-8")
    write_json(folder / MARKER, run)
