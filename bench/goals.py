#!/usr/bin/python3
"""bench/goals.py: compares the figures of a bench/run against their stated goals.

  bench/goals.py FIGURES [--allow-missing] [--markdown OUT.md]

FIGURES holds bench/run's `name: value unit` lines. Prints one row per goal (figure, goal,
measured, PASS / FAIL / not run) and exits 1 when a goal is missed or (without --allow-missing,
which --quick runs pass) a figure with a goal was not measured. --markdown writes the same rows as
a Markdown table (bench/RESULTS.md's goal table), with the rows without a goal (context) too.

Each goal names its source: where the number was asked for, or "set here" when no number was stated
anywhere and this file sets one (change it here, in one place).
"""
import re
import sys

ISSUE12 = "issue 12"
ISSUE15 = "issue 15"
ISSUE22 = "issue 22"
ISSUE26 = "issue 26"
ISSUE33 = "issue 33"
ISSUE36 = "issue 36"
SET_HERE = "set here"


def read_figures(path):
    figures = {}
    for line in open(path):
        m = re.match(r"^([A-Za-z0-9_.%-]+): ([-+0-9.eEinfa]+)( .*)?$", line.strip())
        if m:
            try:
                figures[m.group(1)] = (float(m.group(2)), (m.group(3) or "").strip())
            except ValueError:
                pass
    return figures


class Missing(Exception):
    pass


def main(argv):
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    figures = read_figures(argv[1])
    allow_missing = "--allow-missing" in argv
    markdown = argv[argv.index("--markdown") + 1] if "--markdown" in argv else None

    def f(name):
        if name not in figures:
            raise Missing(name)
        return figures[name][0]

    def fmax(*names):
        return max(f(n) for n in names)

    pct = lambda v: "%.1f %%" % v
    ms = lambda v: "%.4g ms" % v
    sec = lambda v: "%.3g s" % v
    ratio = lambda v: "%.3g" % v
    kb = lambda v: "%+.0f kB" % v

    # (label, measured value (a function of f), comparison, goal, formatter, source);
    # comparison None: context only, no goal.
    rows = [
        ("calibration node at 10 kHz, bursts of 5 (dwell 1.5 s)", lambda: f("node_load_dwell_1.5s_cpu"), "<", 10.0, pct, SET_HERE),
        ("calibration node at 10 kHz, one message per 100 µs", lambda: f("node_load_dwell_1.5s_paced_cpu"), "<", 10.0, pct, SET_HERE),
        ("calibration node at 10 kHz, bursts of 5 (dwell 1.5 s), the dashboard attached", lambda: f("node_load_dwell_1.5s_dashboard_cpu"), None, None, pct, ""),
        ("calibration node at 10 kHz: CPU added by the dashboard attached (with minus without)", lambda: f("node_load_dwell_1.5s_dashboard_cpu") - f("node_load_dwell_1.5s_cpu"), "<=", 0.5, lambda v: "%+.2f points" % v, ISSUE36),
        ("the dashboard itself (Python, one WebSocket client), beside the node at 10 kHz", lambda: f("node_load_dwell_1.5s_dashboard_dashboard_process_cpu"), None, None, pct, ""),
        ("calibration node at 10 kHz, dwells of 10 s / 60 s (worst)", lambda: fmax("node_load_dwell_10s_cpu", "node_load_dwell_60s_cpu"), "<", 10.0, pct, SET_HERE),
        ("calibration node, late drops at 10 kHz (all runs)", lambda: sum(v for k, (v, _) in figures.items() if k.startswith("node_load_") and k.endswith("_dropped_late")) if any(k.endswith("_dropped_late") for k in figures) else f("node_load_dwell_1.5s_dropped_late"), "<=", 0, lambda v: "%.0f" % v, SET_HERE),
        ("calibration node memory growth, dwells of 1.5 / 10 / 60 s (flat)", lambda: fmax("node_load_dwell_1.5s_rss_growth", "node_load_dwell_10s_rss_growth", "node_load_dwell_60s_rss_growth"), "<=", 1024, kb, ISSUE15 + " (flat; 1 MB set here)"),
        ("calibration node memory growth, a 120 s first rest at 10 kHz / 50 kHz (flat)", lambda: fmax("node_load_dwell_1.5s_first_rest_120s_10khz_rss_growth", "node_load_dwell_1.5s_first_rest_120s_50khz_rss_growth"), "<=", 1024, kb, "issue 38"),
        ("calibration node at 10 kHz with a 120 s first rest", lambda: f("node_load_dwell_1.5s_first_rest_120s_10khz_cpu"), "<", 10.0, pct, SET_HERE),
        ("calibration nodelet at 50 kHz (in process, pointers), 5 messages per 100 µs", lambda: f("calibration_nodelet_50khz_paced_cpu"), "<", 5.0, pct, ISSUE26),
        ("calibration nodelet at 50 kHz (in process, pointers), bursts of 25", lambda: f("calibration_nodelet_50khz_bursty_cpu"), "<", 5.0, pct, ISSUE26),
        ("calibration nodelet at 50 kHz: the whole process with the publisher (driver) thread, paced / bursty", lambda: "%.1f / %.1f %%" % (f("calibration_nodelet_50khz_paced_process_cpu"), f("calibration_nodelet_50khz_bursty_process_cpu")), None, None, str, ""),
        ("calibration nodelet at 50 kHz: messages not received or dropped late (all runs)", lambda: sum(f("calibration_nodelet_50khz_%s_%s" % (a, b)) for a in ("paced", "bursty") for b in ("lost", "dropped_late")), "<=", 0, lambda v: "%.0f" % v, ISSUE26),
        ("accelerometer node reading serial lines (t,x,y,z) at 1 kHz from a pseudo-terminal", lambda: f("serial_lines_node_1khz_cpu"), "<", 2.0, pct, ISSUE33),
        ("accelerometer node, serial lines at 1 kHz: samples sent but not received", lambda: f("serial_lines_node_1khz_samples_missing"), "<=", 0, lambda v: "%.0f" % v, SET_HERE),
        ("gimbal controller, ros_joint driver: CPU added by JointState at 1 kHz (minus 10 Hz), the protocol running", lambda: f("ros_joint_controller_1khz_joint_state_handling_cpu"), "<", 1.0, lambda v: "%+.2f points" % v, ISSUE33),
        ("the same stream to a bare roscpp subscriber woken per message (joint_state_sink): CPU added at 1 kHz", lambda: f("ros_joint_controller_1khz_roscpp_floor_cpu"), None, None, lambda v: "%+.2f points" % v, ""),
        ("gimbal controller, ros_joint driver, JointState at 1 kHz / 10 Hz: the whole process", lambda: "%.1f / %.1f %%" % (f("ros_joint_controller_1khz_cpu"), f("ros_joint_controller_10hz_cpu")), None, None, str, ""),
        ("apply node at 10 kHz (TCP in and out), bursts of 5", lambda: f("apply_node_bursty_cpu"), "<", 5.0, pct, ISSUE12),
        ("apply node at 10 kHz (TCP in and out), one message per 100 µs", lambda: f("apply_node_paced_cpu"), "<", 5.0, pct, ISSUE12),
        ("apply nodelet at 10 kHz (in process, pointers), bursts of 5", lambda: f("apply_nodelet_bursty_cpu"), "<", 5.0, pct, ISSUE12),
        ("apply nodelet at 10 kHz (in process, pointers), one message per 100 µs", lambda: f("apply_nodelet_paced_cpu"), "<", 5.0, pct, ISSUE12),
        ("apply node / nodelet: messages not returned (all runs)", lambda: sum(f("apply_%s_%s_lost" % (a, b)) for a in ("node", "nodelet") for b in ("bursty", "paced")), "<=", 0, lambda v: "%.0f" % v, SET_HERE),
        ("apply per-message path (deserialize, correct, serialize)", lambda: f("BM_DeserializeApplySerialize_cpu_percent_at_10khz"), None, None, lambda v: "%.2g %% of a core at 10 kHz" % v, ""),
        ("noise_report analysis, 10^7 samples (three axes)", lambda: f("BM_AnalyzeStaticRecord_10000000_real_time") / 1000.0, "<", 2.0, sec, ISSUE15),
        ("noise_report 10^7 / (10 x 10^6 samples): linear in N", lambda: f("BM_AnalyzeStaticRecord_10000000_real_time") / (10.0 * f("BM_AnalyzeStaticRecord_1000000_real_time")), "<", 2.0, ratio, ISSUE15 + " (factor 2 set here)"),
        ("offline_fit time per 10^6 IMU messages (best run, process start included)", lambda: 1e6 / f("offline_fit_throughput"), "<", 1.0, sec, SET_HERE),
        ("offline_fit throughput", lambda: f("offline_fit_throughput") / 1e6, ">", 1.0, lambda v: "%.2f M msgs/s" % v, SET_HERE),
        ("offline_fit vs a Python rosbag loop", lambda: f("offline_fit_vs_python_loop"), None, None, lambda v: "%.0f x faster" % v, ""),
        ("offline_fit vs real-time replay", lambda: f("offline_fit_vs_realtime_replay"), None, None, lambda v: "%.0f x faster" % v, ""),
        ("fit time, joint, N = 24 positions per phase", lambda: f("fit_time_joint_N24") / 1000.0, None, None, ms, ""),
        ("fit time, joint, N = 3600", lambda: f("fit_time_joint_N3600") / 1000.0, "<", 10.0, ms, SET_HERE),
        ("fit time, eq4, N = 3600", lambda: f("fit_time_eq4_N3600") / 1000.0, "<", 10.0, ms, SET_HERE),
        ("fit time, joint + one effect (Ceres), N = 3600", lambda: f("fit_time_joint_effect_N3600"), "<", 1000.0, ms, SET_HERE),
        ("fit time vs N: RMS off a straight line (worst of joint, eq4, effect)", lambda: fmax("fit_complexity_joint_rms", "fit_complexity_eq4_rms", "fit_complexity_joint_effect_rms"), "<", 20.0, pct, SET_HERE + " (linear)"),
        ("estimator scatter / Cramér–Rao bound (joint, eq4), furthest from 1", lambda: max((v for k, (v, _) in figures.items() if "scatter_over_crb_" in k), key=lambda v: abs(v - 1.0)) if any("scatter_over_crb_" in k for k in figures) else f("scatter_over_crb_responsivity_u"), "within", (0.95, 1.05), ratio, SET_HERE),
        ("reported standard uncertainty / scatter, furthest from 1", lambda: max((v for k, (v, _) in figures.items() if k.startswith("reported_std_over_scatter_")), key=lambda v: abs(v - 1.0)) if any(k.startswith("reported_std_over_scatter_") for k in figures) else f("reported_std_over_scatter_responsivity_u"), "within", (0.95, 1.05), ratio, SET_HERE),
        ("detection threshold / theory, quadratic non-linearity (family-wise)", lambda: f("detection_quadratic_nonlinearity_u_ratio_to_theory_familywise"), "within", (0.8, 1.25), ratio, SET_HERE),
        ("hand tumble: rest detection + fit, simulated 100 Hz session", lambda: f("BM_TumbleSimulated_samples_per_s") / 1e6, ">=", 10.0, lambda v: "%.1f M samples/s" % v, ISSUE22),
        ("hand tumble: rest detection + fit, imu_tk's Xsens session (imu_tk: 0.50 s)", lambda: f("BM_TumbleImuTkXsens_samples_per_s") / 1e6, ">=", 10.0, lambda v: "%.1f M samples/s" % v, ISSUE22),
        ("mount check (supervise --check-mount) on the simulated stand, real time", lambda: f("mount_check_wall_s"), "<", 60.0, sec, ISSUE33),
        ("detection threshold / theory, angle offset (family-wise)", lambda: f("detection_angle_offset_x_ratio_to_theory_familywise"), "within", (0.8, 1.25), ratio, SET_HERE),
    ]

    def goal_text(cmp, goal, fmt):
        if cmp is None:
            return "—"
        if cmp == "within":
            return "%s … %s" % (fmt(goal[0]), fmt(goal[1]))
        return "%s %s" % ({"<=": "≤", ">=": "≥"}.get(cmp, cmp), fmt(goal))

    results = []
    misses = 0
    for label, value, cmp, goal, fmt, source in rows:
        try:
            v = value()
        except Missing as e:
            status = "not run" if allow_missing or cmp is None else "FAIL"
            if status == "FAIL":
                misses += 1
            results.append((label, goal_text(cmp, goal, fmt), "not measured (%s)" % e, status, source))
            continue
        if cmp is None:
            ok = None
        elif cmp == "<":
            ok = v < goal
        elif cmp == "<=":
            ok = v <= goal
        elif cmp == ">":
            ok = v > goal
        elif cmp == ">=":
            ok = v >= goal
        else:
            ok = goal[0] <= v <= goal[1]
        status = "" if ok is None else ("PASS" if ok else "FAIL")
        misses += ok is False
        results.append((label, goal_text(cmp, goal, fmt), fmt(v), status, source))

    width = max(len(r[0]) for r in results)
    print("%-*s  %-18s  %-28s  %s" % (width, "figure", "goal", "measured", "result"))
    for label, goal, measured, status, source in results:
        if goal == "—":
            continue
        print("%-*s  %-18s  %-28s  %s" % (width, label, goal, measured, status))
    if markdown:
        with open(markdown, "w") as out:
            out.write("| figure | goal (source) | measured | result |\n|---|---|---|---|\n")
            for label, goal, measured, status, source in results:
                goal_cell = goal if not source else "%s (%s)" % (goal, source)
                out.write("| %s | %s | %s | %s |\n" % (label, goal_cell, measured, status or "—"))
    print("%d goal(s) missed" % misses if misses else "every goal met")
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
