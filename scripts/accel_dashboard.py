"""The lab dashboard's state, ROS-free (docs/design.md section 17, docs/dashboard.md).

scripts/dashboard feeds a Hub with what the stands publish (calibration/status,
gimbal_controller/progress, calibration/dwell, calibration/result, calibration/tumble_progress,
turned into plain dicts) and with the namespaces the master lists; the Hub keeps one Stand per
namespace and hands every change to its listener as a JSON-ready event for the browsers:

  {"type": "snapshot", "stands": [card, ...]}      every stand, its dwells included (on connect)
  {"type": "stand", "stand": card}                 a stand's card without its dwells
  {"type": "dwell", "ns": ns, "dwell": {...}, "fits": {...}, "rows": n}
  {"type": "archive", "archive": {...}}             the lab archive's view (with ~archive)

The fitted curve of the plot is equation (4) of docs/design.md per phase and accelerometer,
R(a) = c0 + c_sin sin a + c_cos cos a, fitted by unweighted least squares to the dwells of that
phase so far (fit_eq4): the dashboard's own picture of the data, refitted at every dwell; the
numbers of the result come from the calibration node, never from this fit.
"""

import math
import threading
import time

import numpy as np

PHASES = ("x", "y", "z")
ACCEL = ("u", "v", "w")
PHASE_UNKNOWN = 255  # accel_intrinsics/Dwell.PHASE_UNKNOWN: a rest of a hand tumble
# Terminal words of calibration/status "state" (ros/conversions.h to_status_msg).
TERMINAL_STATES = ("RESULT", "FAILED", "ABORTED")
MAX_FAULTS = 20


def finite_or_none(x):
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def fit_eq4(angles, values):
    """Least squares of values = c0 + c_sin sin(a) + c_cos cos(a); [c0, c_sin, c_cos], or None
    with fewer than 3 points or angles that do not determine the three (all alike)."""
    if len(angles) < 3:
        return None
    a = np.asarray(angles, dtype=float)
    design = np.column_stack([np.ones_like(a), np.sin(a), np.cos(a)])
    if np.linalg.matrix_rank(design) < 3:
        return None
    coef, _, _, _ = np.linalg.lstsq(design, np.asarray(values, dtype=float), rcond=None)
    return [float(c) for c in coef]


def eq4_value(coef, angle):
    return coef[0] + coef[1] * math.sin(angle) + coef[2] * math.cos(angle)


def result_to_dict(r):
    """An IntrinsicResult-like object (the message) as the card's result."""
    return {
        "model": r.model,
        "responsivity": list(r.responsivity),
        "responsivity_std": list(r.responsivity_std),
        "angles_deg": list(r.angles_deg),
        "angles_std_deg": list(r.angles_std_deg),
        "offset": list(r.offset),
        "offset_std": list(r.offset_std),
        "local_gravity": r.local_gravity,
        "reduced_chi2": r.reduced_chi2,
        "residual_rms": r.residual_rms,
        "positions": [int(p) for p in r.positions],
        "quality_pass": bool(r.quality_pass),
        "quality_reasons": list(r.quality_reasons),
        "effects": [
            {"name": n, "target": t, "value": v, "std": s}
            for n, t, v, s in zip(r.effect_names, r.effect_targets, r.effect_values, r.effect_std)
        ],
        "stamp": r.header.stamp.to_sec(),
    }


def dwell_to_dict(d):
    """A Dwell-like object (the message) as a plotted point."""
    phase = PHASES[d.phase] if d.phase < len(PHASES) else "-"
    return {
        "index": int(d.index),
        "phase": phase,
        "step": int(d.step),
        "angle": d.angle,
        "n": int(d.n),
        "mean": [float(m) for m in d.mean],
        "std": [float(s) for s in d.std],
        "temperature": finite_or_none(d.temperature),
        "t_end": d.t_end,
    }


class Stand:
    """One stand (namespace): what its topics said last, and since when nothing."""

    def __init__(self, ns, now):
        self.ns = ns
        self.device = ""  # ~archive_device of its calibration node, a user's string
        self.status = {}  # calibration/status key/values
        self.status_level = 0
        self.status_message = ""
        self.progress = {}  # gimbal_controller/progress key/values
        self.progress_level = 0
        self.progress_message = ""
        self.tumble = None  # calibration/tumble_progress JSON
        self.dwells = {}  # table row index -> dwell dict
        self.result = None
        self.faults = []  # [{"time": wall s, "source": ..., "text": ...}], newest last
        self.last_heard = now
        self.lost = ""  # why it is lost, "" while it is heard
        self.on_master = True

    def fault(self, source, text, now):
        text = (text or "").strip()
        if not text or any(f["text"] == text and f["source"] == source for f in self.faults):
            return
        self.faults.append({"time": now, "source": source, "text": text})
        del self.faults[:-MAX_FAULTS]

    def fits(self):
        """{phase: {accel: [c0, c_sin, c_cos]}} of the phases with enough dwells."""
        out = {}
        for p in PHASES:
            rows = [d for d in self.dwells.values() if d["phase"] == p]
            per_accel = {}
            for i, a in enumerate(ACCEL):
                coef = fit_eq4([d["angle"] for d in rows], [d["mean"][i] for d in rows])
                if coef is not None:
                    per_accel[a] = coef
            if per_accel:
                out[p] = per_accel
        return out

    def card(self, with_dwells):
        state = self.status.get("state", "") or ("TUMBLE" if self.tumble is not None else "")
        c = {
            "ns": self.ns,
            "device": self.device,
            "state": state,
            "run_state": self.status.get("run_state", ""),
            "status_message": self.status_message,
            "status_level": self.status_level,
            "controller_state": self.progress.get("state", ""),
            "controller_message": self.progress_message,
            "controller_level": self.progress_level,
            "phase": self.progress.get("phase", ""),
            "step": self.progress.get("step", ""),
            "steps": self.progress.get("steps", self.status.get("steps", "")),
            "position": self.progress.get("position", ""),
            "positions": self.progress.get("positions", ""),
            "fraction": finite_or_none(self.progress.get("fraction")),
            "time_left_s": finite_or_none(self.progress.get("time_left_s")),
            "dwells_per_phase": [self.status.get("dwells_" + p, "") for p in PHASES],
            "rows": len(self.dwells),
            "tumble": self.tumble,
            "result": self.result,
            "faults": list(self.faults),
            "lost": self.lost,
        }
        if with_dwells:
            c["dwells"] = [self.dwells[k] for k in sorted(self.dwells)]
            c["fits"] = self.fits()
        return c


class Hub:
    """Every stand under the master. Thread safe: ROS callbacks, the discovery thread and the
    web server call it; `listener(event)` is called with each event (under the hub's lock, so in
    order; it must only hand the event on, e.g. to the web server's loop)."""

    def __init__(self, lost_after_s=3.0, clock=time.monotonic, listener=None):
        self.lost_after_s = lost_after_s
        self.clock = clock
        self.listener = listener or (lambda event: None)
        self.lock = threading.Lock()
        self.stands = {}
        self.archive = None  # accel_dashboard_archive.ArchiveView.read(), with ~archive

    # ---- inputs ----------------------------------------------------------------------------

    def _stand(self, ns):
        s = self.stands.get(ns)
        if s is None:
            s = self.stands[ns] = Stand(ns, self.clock())
        return s

    def _heard(self, s):
        s.last_heard = self.clock()
        if s.lost:
            s.fault("dashboard", "heard again after: " + s.lost, s.last_heard)
            s.lost = ""

    def _emit_stand(self, s):
        self.listener({"type": "stand", "stand": s.card(False)})

    def on_status(self, ns, level, message, values):
        """calibration/status (diagnostic_msgs/DiagnosticStatus as level, message, {key: value})."""
        with self.lock:
            s = self._stand(ns)
            self._heard(s)
            s.status, s.status_level, s.status_message = dict(values), level, message
            for key in ("fault", "last_fault"):
                s.fault("calibration", values.get(key, ""), s.last_heard)
            if level >= 2:
                s.fault("calibration", message, s.last_heard)
            self._emit_stand(s)

    def on_progress(self, ns, level, message, values):
        """gimbal_controller/progress: its message is the controller's (the device's) words."""
        with self.lock:
            s = self._stand(ns)
            self._heard(s)
            s.progress, s.progress_level, s.progress_message = dict(values), level, message
            if level >= 1:
                s.fault("gimbal_controller", message, s.last_heard)
            self._emit_stand(s)

    def on_tumble(self, ns, progress):
        with self.lock:
            s = self._stand(ns)
            self._heard(s)
            s.tumble = progress
            self._emit_stand(s)

    def on_dwell(self, ns, dwell):
        """One row of the stand's position table; a row number already held means the table was
        cut back (a reset, a new run, a position measured again): later rows go."""
        with self.lock:
            s = self._stand(ns)
            self._heard(s)
            i = dwell["index"]
            for k in [k for k in s.dwells if k >= i]:
                del s.dwells[k]
            if i == 0:
                s.result = None  # a new run
            s.dwells[i] = dwell
            self.listener({"type": "dwell", "ns": ns, "dwell": dwell, "fits": s.fits(),
                           "rows": len(s.dwells)})
            self._emit_stand(s)

    def on_result(self, ns, result):
        with self.lock:
            s = self._stand(ns)
            self._heard(s)
            s.result = result
            self._emit_stand(s)

    def set_device(self, ns, device):
        with self.lock:
            s = self.stands.get(ns)
            if s is not None and s.device != device:
                s.device = device
                self._emit_stand(s)

    def on_master(self, namespaces):
        """The stand namespaces the master lists now. A stand that left it is lost at once."""
        with self.lock:
            now = self.clock()
            for ns in namespaces:
                if ns not in self.stands:
                    self._stand(ns)
                    self._emit_stand(self.stands[ns])
                self.stands[ns].on_master = True
            for ns, s in self.stands.items():
                if ns not in namespaces and s.on_master:
                    s.on_master = False
                    if not s.lost:
                        s.lost = "its nodes left the ROS master"
                        s.fault("dashboard", "lost: " + s.lost, now)
                        self._emit_stand(s)

    def check_lost(self):
        """A stand silent for lost_after_s (wall time) is lost: killed, its PC or network down."""
        with self.lock:
            now = self.clock()
            for s in self.stands.values():
                silent = now - s.last_heard
                if not s.lost and silent > self.lost_after_s:
                    s.lost = "no message for %.1f s" % silent
                    s.fault("dashboard", "lost: " + s.lost, now)
                    self._emit_stand(s)

    def set_archive(self, view):
        """The lab archive's devices and histories (only sent when they changed)."""
        with self.lock:
            if view != self.archive:
                self.archive = view
                self.listener({"type": "archive", "archive": view})

    # ---- outputs ---------------------------------------------------------------------------

    def snapshot(self):
        with self.lock:
            return {"type": "snapshot", "archive": self.archive,
                    "stands": [self.stands[ns].card(True) for ns in sorted(self.stands)]}
