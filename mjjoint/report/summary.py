"""Plain-text summaries for the terminal: parameter tables, NRMSE before -> after, the verdict."""
from __future__ import annotations

from ..diagnosis.open_starts import left_out_line
from ..diagnosis.revise import revision_line
from ..identify.effects import BASE_PARAMS, EFFECTS, Param

SIGNAL_ORDER = ("q", "theta", "delta", "tau")


def params_by_name() -> dict[str, Param]:
    return {p.name: p for p in BASE_PARAMS + tuple(p for e in EFFECTS.values() for p in e.params)}


def flagged(name: str, warnings) -> bool:
    """Whether a fit warning names parameter ``name`` (e.g. unidentifiable, on a bound)."""
    return any(w.startswith(f"{name} ") for w in warnings)


def parameter_rows(parameters: dict[str, float], intervals: dict, warnings,
                   units: dict[str, str] | None = None) -> list[tuple[str, str, str, str, bool]]:
    """(name, value, 95 % interval, unit, flagged) per parameter, formatted for people.

    ``units``: the structure's own (a linear drive's are N and m); default the catalogue's.
    """
    meta = {k: p.unit for k, p in params_by_name().items()} | (units or {})
    rows = []
    for name, value in parameters.items():
        iv = intervals.get(name)
        interval = "-" if iv is None else f"[{iv[0]:.3g}, {iv[1]:.3g}]"
        unit = meta.get(name, "")
        rows.append((name, f"{value:.4g}", interval, unit, flagged(name, warnings)))
    return rows


def parameter_table(parameters: dict[str, float], intervals: dict, warnings, units=None) -> str:
    rows = parameter_rows(parameters, intervals, warnings, units)
    width = max([len("parameter")] + [len(r[0]) for r in rows])
    lines = [f"  {'parameter':{width}s}  {'value':>11s}  {'95 % interval':26s}  unit"]
    for name, value, interval, unit, flag in rows:
        lines.append(f"{'!' if flag else ' '} {name:{width}s}  {value:>11s}  {interval:26s}  {unit}".rstrip())
    if warnings:
        lines.append("warnings (! above):")
        lines += [f"  - {w}" for w in warnings]
    return "\n".join(lines)


def step_values(step: dict, final: dict) -> dict[str, float]:
    """A step's parameters at their final fitted values, plus its effect's discrete settings
    (e.g. the ripple harmonic), from diagnosis.json data."""
    values = {n: final["parameters"].get(n, v) for n, v in step["parameters"].items()}
    prefix = f"{step['effect']}."
    values.update({k: v for k, v in final.get("settings", {}).items() if k.startswith(prefix)})
    return values


def none_named(explained: bool) -> str:
    """What a table says of a diagnosis that named no effect: whether its model explains the recording."""
    return "none named; explained to the noise" if explained else "none named; a mismatch remains"


def nrmse_lines(before: dict[str, float], after: dict[str, float] | None = None) -> list[str]:
    """One line per signal: held-out NRMSE, and its change when ``after`` is given."""
    out = []
    for s in SIGNAL_ORDER:
        if s not in before:
            continue
        b = before[s]
        if after is None:
            out.append(f"  {s:6s} {_num(b)}")
        else:
            a = after[s]
            change = "" if not (b and b == b and a == a) else f"  ({100 * (a / b - 1):+.0f} %)"
            out.append(f"  {s:6s} {_num(b)} -> {_num(a)}{change}")
    return out


def _num(x) -> str:
    return "   n/a" if x is None or x != x else f"{x:.4f}"


def diagnosis_summary(diag: dict, seconds: float) -> str:
    """What the user reads at the end of ``mjjoint diagnose`` (``diag``: diagnosis.json data)."""
    lines = [f"verdict: {diag['verdict']}"]
    steps = diag["steps"]
    if steps:
        lines.append("missing effects, in the order found:")
        final = diag["final_model"]
        for k, st in enumerate(steps, 1):
            e = st["effect"]
            with_ = st.get("prerequisites_added") or []
            label = e + (f" (with {', '.join(with_)})" if with_ else "")
            lines.append(f"  {k}. {label} - {EFFECTS[e].physics}; held-out cost "
                         f"{-100 * st['heldout_gain']:+.1f} %")
            for name, value, interval, unit, flag in parameter_rows(
                    step_values(st, final), final["intervals_95"], final["warnings"], final.get("units")):
                ci = "" if interval == "-" else f"  95 % {interval}"
                lines.append(f"       {name} = {value} {unit}".rstrip() + ci + ("  (!)" if flag else ""))
    revised = revision_lines(diag)
    if revised:
        lines.append("revisions of the search (diagnosis.json \"revisions\"):")
        lines += [f"  - {line}" for line in revised]
    if diag.get("heldout_left_out_s"):
        lines.append(left_out_line(diag["heldout_left_out_s"]))
    lines.append("held-out NRMSE per signal (base model -> final model; noise floor):")
    lines += judged_lines(diag, diag["initial_fit"]["nrmse_heldout"], diag["final_fit"]["nrmse_heldout"])
    if diag["final_model"]["warnings"]:
        lines.append("fit warnings:")
        lines += [f"  - {w}" for w in diag["final_model"]["warnings"]]
    lines.append(f"budget: {diag['budget']['rollouts_full_length']:g} full-length rollouts, "
                 f"{seconds:.1f} s wall time")
    return "\n".join(lines)


def judged_lines(data: dict, before: dict[str, float], after: dict[str, float] | None = None) -> list[str]:
    """``nrmse_lines`` with each signal's noise floor, and whether the recording is explained to
    the noise, from ``data``'s "noise_floor" and "explained" (diagnosis.json, fit.json)."""
    floor = (data.get("noise_floor") or {}).get("nrmse", {})
    twin = (data.get("noise_floor") or {}).get("twin_nrmse", {})

    def floor_of(s: str) -> str:  # the twin beside a floor that counts it only in part
        if s not in floor:
            return ""
        return f"   floor {floor[s]:.4f}" + (f" (twin {twin[s]:.4f})" if twin.get(s, 0.0) > floor[s] else "")
    shown = [s for s in SIGNAL_ORDER if s in before]  # nrmse_lines' order
    lines = [line + floor_of(s) for s, line in zip(shown, nrmse_lines(before, after))]
    return [*lines, f"explained to the noise: {'yes' if data.get('explained') else 'no'}"]


def revision_lines(diag: dict) -> list[str]:
    """One line per revision of the search (swaps, removals, effects refused as stand-ins), from
    diagnosis.json data."""
    return [("not named, a stand-in: " if r["kind"] == "stand-in" else "") + revision_line(r)
            for r in diag.get("revisions", [])]
