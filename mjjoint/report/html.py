"""``index.html``: one plain page tying the figures and numbers together (no scripts, no CDN).

Images are referenced by relative path, so the folder can be moved or zipped as a whole.
"""
from __future__ import annotations

from html import escape

from ..diagnosis.floor import EXPLAINED_RATIO
from ..identify.effects import EFFECTS
from .summary import SIGNAL_ORDER, parameter_rows, revision_lines, step_values

FLOOR_NOTE = f"{EXPLAINED_RATIO:g}x its noise floor, diagnosis/floor.py"
STYLE = """
body { font-family: sans-serif; max-width: 1060px; margin: 2em auto; color: #222; }
.verdict { font-size: 1.25em; padding: .6em .9em; border-left: 6px solid #2a7; background: #eef8f1; }
.verdict.found { border-color: #d70; background: #fdf3e6; }
table { border-collapse: collapse; margin: .6em 0 1.2em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; vertical-align: top; }
td.num { text-align: right; font-family: monospace; }
tr.flag td { background: #fff4d6; }
img { max-width: 100%; border: 1px solid #ddd; margin: .4em 0; }
code { background: #f3f3f3; padding: 0 .2em; }
.muted { color: #666; font-size: .9em; }
"""


def _page(title: str, body: list[str]) -> str:
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


def _img(path: str, alt: str) -> str:
    return f'<p><img src="{escape(path)}" alt="{escape(alt)}"></p>'


def _num(x) -> str:
    return "n/a" if x is None or x != x else f"{x:.4f}"


def nrmse_table(columns: dict[str, dict[str, float]]) -> str:
    """Signals as rows, one column per model (e.g. base model, final model)."""
    heads = "".join(f"<th>{escape(c)}</th>" for c in columns)
    rows = []
    for s in SIGNAL_ORDER:
        if all(s in v for v in columns.values()):
            cells = "".join(f'<td class="num">{_num(v[s])}</td>' for v in columns.values())
            rows.append(f"<tr><td>{escape(s)}</td>{cells}</tr>")
    return f"<table><tr><th>signal</th>{heads}</tr>{''.join(rows)}</table>"


def parameter_table(parameters: dict[str, float], intervals: dict, warnings, units=None) -> str:
    rows = []
    for name, value, interval, unit, flag in parameter_rows(parameters, intervals, warnings, units):
        rows.append(f'<tr{" class=flag" if flag else ""}><td><code>{escape(name)}</code></td>'
                    f'<td class="num">{escape(value)}</td><td class="num">{escape(interval)}</td>'
                    f"<td>{escape(unit)}</td></tr>")
    table = ("<table><tr><th>parameter</th><th>value</th><th>95 % interval</th><th>unit</th></tr>"
             + "".join(rows) + "</table>")
    if warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in warnings)
        table += f"<p>Warnings (highlighted rows):</p><ul>{items}</ul>"
    return table


def _where(where: dict) -> str:
    sig = where.get("signal", "?")
    wins = ", ".join(f"{w[0]:.2f}-{w[1]:.2f} s ({100 * w[2]:.0f} %)" for w in where.get("windows", []))
    return f"worst signal <code>{escape(sig)}</code>; residual energy in {escape(wins) or 'no window'}"


def _step(k: int, step: dict, final: dict, image: str | None) -> list[str]:
    e = step["effect"]
    evidence = step["evidence"] or ["no located condition names this effect; the held-out gain decided"]
    before, after = step["fit_before"], step["fit_after"]
    screened = ", ".join(f"{escape(n)} {c:.4g}" for n, c in sorted(step["screened"].items(), key=lambda kv: kv[1]))
    params = step_values(step, final)
    ptable = parameter_table(params, final["intervals_95"], final["warnings"], final.get("units"))
    out = [f"<h2>Step {k}: <code>{escape(e)}</code></h2>",
           f"<p>{escape(EFFECTS[e].physics)}. Held-out cost {-100 * step['heldout_gain']:+.1f} %.</p>",
           "<table>",
           "<tr><th>evidence</th><td><ul>" + "".join(f"<li>{escape(x)}</li>" for x in evidence) + "</ul></td></tr>",
           f"<tr><th>where</th><td>{_where(step['where'])}</td></tr>",
           f"<tr><th>parameters (final fit)</th><td>{ptable}</td></tr>",
           f"<tr><th>held-out NRMSE</th><td>{nrmse_table({'before': before, 'after': after})}</td></tr>",
           f"<tr><th>screened candidates (held-out cost, {escape(step['screen'])})</th><td>{screened}</td></tr>",
           "</table>"]
    if image:
        out.append(_img(image, f"evidence for {e}"))
    return out


def diagnosis_page(diag: dict, images: dict, source: str, run: dict) -> str:
    """The page of ``mjjoint diagnose``; ``images``: overview paths and one per step."""
    found = bool(diag["steps"])
    body = [f"<h1>mjjoint diagnose: {escape(source)}</h1>",
            f'<p class="verdict{" found" if found else ""}">{escape(diag["verdict"])}</p>']
    if found:
        body.append("<p>Missing, in the order found: " + ", ".join(
            f"<code>{escape(s['effect'])}</code>" for s in diag["steps"]) + "</p>")
    body += ["<h2>Held-out prediction error</h2>",
             "<p>NRMSE of the windowed predictions on held-out windows (rms error / the signal's spread).</p>",
             nrmse_table({"base model": diag["initial_fit"]["nrmse_heldout"],
                          "final model": diag["final_fit"]["nrmse_heldout"],
                          **({"noise floor": diag["noise_floor"]["nrmse"]} if diag.get("noise_floor") else {})}),
             f"<p>Explained to the noise (every signal within {FLOOR_NOTE}): "
             f"<b>{'yes' if diag.get('explained') else 'no'}</b>.</p>",
             _img(images["windows"], "measured vs predicted on held-out windows"),
             _img(images["residual"], "residual over time with located windows")]
    for k, step in enumerate(diag["steps"], 1):
        body += _step(k, step, diag["final_model"], images["steps"][k - 1])
    revised = revision_lines(diag)
    if revised:
        body += ["<h2>Revisions of the search</h2>",
                 "<ul>" + "".join(f"<li>{escape(line)}</li>" for line in revised) + "</ul>"]
    final = diag["final_model"]
    body += ["<h2>Final model</h2>",
             "<p>Effects: " + (", ".join(f"<code>{escape(e)}</code>" for e in final["effects"]) or "minimal") + "</p>",
             parameter_table({**final["parameters"], **final.get("settings", {})}, final["intervals_95"],
                             final["warnings"], final.get("units")),
             _files(run)]
    return _page(f"mjjoint diagnose: {source}", body)


def fit_page(fit: dict, images: dict, source: str, run: dict) -> str:
    """The page of ``mjjoint fit``."""
    st = fit["structure"]
    body = [f"<h1>mjjoint fit: {escape(source)}</h1>",
            "<p>Effects: " + (", ".join(f"<code>{escape(e)}</code>" for e in st["effects"]) or "minimal") + "</p>",
            "<h2>Parameters</h2>",
            parameter_table(st["parameters"], fit["intervals_95"], fit["warnings"], st.get("units")),
            "<h2>Prediction error (NRMSE)</h2>",
            nrmse_table({"training windows": fit["nrmse_train"], "held-out windows": fit["nrmse_test"]}),
            _img(images["windows"], "measured vs fitted on held-out windows"),
            _img(images["residual"], "residual over time"),
            _files(run)]
    return _page(f"mjjoint fit: {source}", body)


def _files(run: dict) -> str:
    return ("<h2>Files and budget</h2><ul>"
            + "".join(f"<li><code>{escape(f)}</code></li>" for f in run["files"])
            + "</ul><p class=\"muted\">Open <code>traces.rrd</code> with <code>rerun traces.rrd</code>. "
            f"{run['rollouts_full_length']:g} full-length rollouts, {run['seconds']:.1f} s wall time.</p>")
