"""The history of a device and the control chart of a check standard (docs/design.md section 13):
pure functions of archive records (accel_archive.fetch_records), no database, so the tests build
records by hand.

A record here is a dict with `time` (naive UTC datetime), `rig`, `method`, `values` {name: x}
and `expanded` {name: U} (the expanded uncertainty, k = 2 unless the result's budget said
otherwise; the standard uncertainty is U / 2 for the weights).
"""

import datetime
import math

import numpy as np

from accel_archive import DEFAULT_K, PARAMETER_NAMES, iso, parse_time

SECONDS_PER_DAY = 86400.0
LABELS = {"responsivity_u": "|u|", "responsivity_v": "|v|", "responsivity_w": "|w|",
          "angle_uv": "angle uv (deg)", "angle_vw": "angle vw (deg)", "angle_wu": "angle wu (deg)",
          "offset_u": "O_u", "offset_v": "O_v", "offset_w": "O_w"}
# A drift is taken as real (and a recalibration date predicted) when |rate| exceeds this many
# standard uncertainties of the rate: the same k as the expanded uncertainties.
DRIFT_SIGNIFICANCE_K = DEFAULT_K


def en(x_a, U_a, x_b, U_b):
    """Normalized error E_n = (x_a - x_b) / sqrt(U_a^2 + U_b^2) (compare_results' definition)."""
    denominator = math.sqrt(U_a * U_a + U_b * U_b)
    return (x_a - x_b) / denominator if denominator > 0 else None


def days_between(a, b):
    return (b - a).total_seconds() / SECONDS_PER_DAY


def weighted_line(t, x, u):
    """Weighted least-squares line x = a + b t with standard uncertainties u: (a, b, cov, chi2,
    dof). The covariance is scaled by the reduced chi-square when that exceeds 1 (the scatter
    says the uncertainties are too small), as the fits do."""
    t, x, u = np.asarray(t, float), np.asarray(x, float), np.asarray(u, float)
    A = np.column_stack([np.ones_like(t), t]) / u[:, None]
    y = x / u
    normal = A.T @ A
    cov = np.linalg.inv(normal)
    coefficients = cov @ (A.T @ y)
    residual = y - A @ coefficients
    chi2 = float(residual @ residual)
    dof = len(t) - 2
    if dof > 0 and chi2 / dof > 1.0:
        cov = cov * (chi2 / dof)
    return float(coefficients[0]), float(coefficients[1]), cov, chi2, dof


def history(records):
    """The history document of one device's records (oldest first)."""
    records = sorted(records, key=lambda r: r["time"])
    out = {
        "records": [{"id": r.get("id"), "time": iso(r["time"]), "rig": r.get("rig", ""),
                     "method": r.get("method", ""), "values": dict(r["values"]),
                     "expanded": dict(r["expanded"])} for r in records],
        "E_n_consecutive": {},
        "drift": {},
        "recalibrate_by": {},
    }
    for name in PARAMETER_NAMES:
        out["E_n_consecutive"][name] = [
            en(b["values"][name], b["expanded"][name], a["values"][name], a["expanded"][name])
            for a, b in zip(records, records[1:])]
        out["drift"][name] = None
        out["recalibrate_by"][name] = None
    if len(records) < 2:
        return out
    t0 = records[0]["time"]
    t = [days_between(t0, r["time"]) for r in records]
    if max(t) - min(t) <= 0:
        return out  # all on one day: no rate
    last = records[-1]
    for name in PARAMETER_NAMES:
        x = [r["values"][name] for r in records]
        u = [r["expanded"][name] / DEFAULT_K for r in records]
        if min(u) <= 0:
            continue
        _, rate, cov, chi2, dof = weighted_line(t, x, u)
        rate_std = math.sqrt(cov[1, 1])
        significant = abs(rate) > DRIFT_SIGNIFICANCE_K * rate_std
        out["drift"][name] = {"rate_per_day": rate, "rate_std_per_day": rate_std,
                              "significant": bool(significant), "chi2": chi2, "dof": dof}
        if significant and rate != 0:
            # The drift since the last calibration reaches that calibration's expanded
            # uncertainty after U / |rate| days.
            days = last["expanded"][name] / abs(rate)
            when = last["time"] + datetime.timedelta(days=days)
            out["recalibrate_by"][name] = when.date().isoformat()
    dates = [(d, n) for n, d in out["recalibrate_by"].items() if d]
    out["recalibrate_first"] = ({"date": min(dates)[0], "parameter": min(dates)[1]}
                                if dates else None)
    return out


def weighted_mean(values, expanded):
    w = np.array([1.0 / (U / DEFAULT_K) ** 2 for U in expanded])
    return float(np.dot(w, values) / w.sum())


def run_rule_flags(times, deviations, expanded, parameter):
    """Flags of the usual run rules on one parameter's chart: `beyond_3U` (one point beyond 3U),
    `two_of_three_beyond_2U` (two of three consecutive points beyond 2U on the same side; flagged
    at the point that completes them), `seven_one_side` (seven or more consecutive points on one
    side of the reference; flagged from the seventh on). U is each point's expanded uncertainty."""
    flags = []
    n = len(deviations)
    for i in range(n):
        d, U = deviations[i], expanded[i]
        if abs(d) > 3.0 * U:
            flags.append({"time": times[i], "parameter": parameter, "rule": "beyond_3U",
                          "index": i})
        if i >= 1:
            window = range(max(0, i - 2), i + 1)
            for side in (1.0, -1.0):
                beyond = [j for j in window if side * deviations[j] > 2.0 * expanded[j]]
                # flagged at the point that completes the pair (so it is flagged once)
                if len(beyond) >= 2 and i in beyond:
                    flags.append({"time": times[i], "parameter": parameter,
                                  "rule": "two_of_three_beyond_2U", "index": i})
        if i >= 6:
            run = deviations[i - 6:i + 1]
            if all(v > 0 for v in run) or all(v < 0 for v in run):
                flags.append({"time": times[i], "parameter": parameter,
                              "rule": "seven_one_side", "index": i})
    return flags


def control_chart(records, reference=None):
    """The control chart document of a check standard's records on one rig (oldest first).
    `reference` {name: value}: the standard's reference values; default the weighted mean of
    the records."""
    records = sorted(records, key=lambda r: r["time"])
    if not records:
        return {"reference": {}, "points": [], "flags": []}
    times = [iso(r["time"]) for r in records]
    if reference is None:
        reference = {name: weighted_mean([r["values"][name] for r in records],
                                         [r["expanded"][name] for r in records])
                     for name in PARAMETER_NAMES}
    out = {"reference": dict(reference), "points": [], "flags": []}
    for time, r in zip(times, records):
        out["points"].append({
            "time": time, "id": r.get("id"), "rig": r.get("rig", ""),
            "values": dict(r["values"]), "expanded": dict(r["expanded"]),
            "deviation": {n: r["values"][n] - reference[n] for n in PARAMETER_NAMES}})
    for name in PARAMETER_NAMES:
        deviations = [p["deviation"][name] for p in out["points"]]
        expanded = [p["expanded"][name] for p in out["points"]]
        out["flags"].extend(run_rule_flags(times, deviations, expanded, name))
    out["flags"].sort(key=lambda f: (f["index"], f["parameter"], f["rule"]))
    return out


def compare_rigs(records):
    """Stands on the same device: each rig's latest record and E_n between every two rigs."""
    latest = {}
    for r in sorted(records, key=lambda r: r["time"]):
        latest[r.get("rig", "")] = r
    rigs = sorted(latest)
    out = {"rigs": {rig: {"time": iso(latest[rig]["time"]), "id": latest[rig].get("id"),
                          "values": dict(latest[rig]["values"]),
                          "expanded": dict(latest[rig]["expanded"])} for rig in rigs},
           "E_n_between_rigs": []}
    for i, a in enumerate(rigs):
        for b in rigs[i + 1:]:
            ra, rb = latest[a], latest[b]
            values = {n: en(ra["values"][n], ra["expanded"][n], rb["values"][n], rb["expanded"][n])
                      for n in PARAMETER_NAMES}
            out["E_n_between_rigs"].append({
                "rig_a": a, "rig_b": b, "E_n": values,
                "consistent": all(v is not None and abs(v) <= 1.0 for v in values.values())})
    out["consistent"] = all(p["consistent"] for p in out["E_n_between_rigs"])
    return out


# --- Plots (matplotlib, imported only here) -------------------------------------------------------

def _pyplot():
    import matplotlib
    if matplotlib.get_backend().lower() not in ("agg", "pdf"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _dates(items):
    return [parse_time(p["time"]) for p in items]


def history_figure(doc, title, figsize=(13, 9)):
    """The history plot: each parameter with its U, the drift line, recalibrate_by."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 3, figsize=figsize, sharex=True)
    times = _dates(doc["records"])
    for ax, name in zip(axes.flat, PARAMETER_NAMES):
        values = [r["values"][name] for r in doc["records"]]
        expanded = [r["expanded"][name] for r in doc["records"]]
        ax.errorbar(times, values, yerr=expanded, fmt="o", capsize=3, label="result +- U")
        drift = doc["drift"].get(name)
        if drift and len(times) >= 2:
            # the weighted line through the history, anchored at the weighted mean
            t0 = times[0]
            days = [days_between(t0, t) for t in times]
            w = [1.0 / (U / 2.0) ** 2 for U in expanded]
            mean_t = sum(wi * d for wi, d in zip(w, days)) / sum(w)
            mean_x = sum(wi * v for wi, v in zip(w, values)) / sum(w)
            ends = [min(days), max(days)]
            recal = doc["recalibrate_by"].get(name)
            if recal:
                ends[1] = max(ends[1], days_between(t0, parse_time(recal)))
            line_t = [t0 + datetime.timedelta(days=d) for d in ends]
            line_x = [mean_x + drift["rate_per_day"] * (d - mean_t) for d in ends]
            ax.plot(line_t, line_x, "--", color="C1" if drift["significant"] else "0.6",
                    label="drift %.3g +- %.2g /day" % (drift["rate_per_day"],
                                                       drift["rate_std_per_day"]))
            if recal:
                ax.axvline(parse_time(recal), color="C3", linestyle=":",
                           label="recalibrate by %s" % recal)
        ax.set_title(LABELS[name], fontsize=10)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.autofmt_xdate()
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def chart_figure(doc, title, figsize=(13, 9)):
    """The control chart plot: deviations from the reference, 2U and 3U limits, flags."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 3, figsize=figsize, sharex=True)
    times = _dates(doc["points"])
    for ax, name in zip(axes.flat, PARAMETER_NAMES):
        d = [p["deviation"][name] for p in doc["points"]]
        U = [p["expanded"][name] for p in doc["points"]]
        ax.plot(times, d, "o-", label="result - reference")
        for m, style in ((2, "--"), (3, "-")):
            ax.step(times, [m * u for u in U], style, where="mid", color="C1" if m == 2 else "C3",
                    label="+-%dU" % m)
            ax.step(times, [-m * u for u in U], style, where="mid", color="C1" if m == 2 else "C3")
        ax.axhline(0.0, color="0.5", linewidth=0.8)
        flagged = [(parse_time(f["time"]), doc["points"][f["index"]]["deviation"][name])
                   for f in doc["flags"] if f["parameter"] == name]
        if flagged:
            ax.plot([f[0] for f in flagged], [f[1] for f in flagged], "x", color="C3",
                    markersize=11, label="run rule")
        ax.set_title("%s (reference %.6g)" % (LABELS[name], doc["reference"][name]), fontsize=10)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.autofmt_xdate()
    fig.suptitle(title)
    fig.tight_layout()
    return fig
