"""The dashboard's ROS-free state (scripts/accel_dashboard.py): the eq. (4) curve, the rows of a
stand's table as dwells land and are cut back, and when a stand counts as lost."""

import math
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
import accel_dashboard as ad  # noqa: E402


def dwell(index, phase, step, steps, mean):
    return {"index": index, "phase": phase, "step": step, "angle": 2 * math.pi * step / steps,
            "n": 100, "mean": list(mean), "std": [0.01] * 3, "temperature": None, "t_end": 1.0}


def test_fit_eq4_recovers_the_equation_written_here():
    # R_u in phase y of a device with u = (0.98, 0.02, -0.01), offset 0.05, g = 9.81:
    # f = g (sin a, 0, cos a), so R = 0.05 + 9.81*0.98 sin a - 9.81*0.01 cos a.
    g = 9.81
    angles = [2 * math.pi * n / 7 for n in range(7)]
    values = [0.05 + g * 0.98 * math.sin(a) + g * (-0.01) * math.cos(a) for a in angles]
    coef = ad.fit_eq4(angles, values)
    assert coef == pytest.approx([0.05, g * 0.98, -g * 0.01], abs=1e-12)
    expected = 0.05 + g * 0.98 * math.sin(1.0) - g * 0.01 * math.cos(1.0)
    assert ad.eq4_value(coef, 1.0) == pytest.approx(expected, abs=1e-12)


def test_fit_eq4_needs_three_distinct_angles():
    assert ad.fit_eq4([0.0, 1.0], [1.0, 2.0]) is None
    assert ad.fit_eq4([0.5, 0.5, 0.5], [1.0, 2.0, 3.0]) is None


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_dwells_make_rows_and_fits_and_a_cut_back_table_drops_later_rows():
    events = []
    hub = ad.Hub(clock=Clock(), listener=events.append)
    for n in range(4):
        hub.on_dwell("/rig1", dwell(n, "x", n, 4, (math.cos(2 * math.pi * n / 4), 0.0, 1.0)))
    s = hub.stands["/rig1"]
    assert sorted(s.dwells) == [0, 1, 2, 3]
    fits = [e for e in events if e["type"] == "dwell"][-1]["fits"]
    assert fits["x"]["u"] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert "y" not in fits
    # The position measured again: row 2 comes again, row 3 goes.
    hub.on_dwell("/rig1", dwell(2, "x", 2, 4, (-1.0, 0.0, 1.0)))
    assert sorted(s.dwells) == [0, 1, 2]
    assert hub.snapshot()["stands"][0]["rows"] == 3


def test_silent_stand_is_lost_and_found_again_and_a_stand_off_the_master_is_lost_at_once():
    clock = Clock()
    events = []
    hub = ad.Hub(lost_after_s=3.0, clock=clock, listener=events.append)
    hub.on_status("/a", 0, "collecting", {"state": "COLLECTING"})
    hub.on_status("/b", 0, "collecting", {"state": "COLLECTING"})
    clock.t += 2.9
    hub.on_status("/b", 0, "collecting", {"state": "COLLECTING"})
    hub.check_lost()
    assert hub.stands["/a"].lost == ""
    clock.t += 0.2  # /a silent 3.1 s, /b 0.2 s
    hub.check_lost()
    assert hub.stands["/a"].lost.startswith("no message for 3.1")
    assert hub.stands["/b"].lost == ""
    assert any(e["type"] == "stand" and e["stand"]["ns"] == "/a" and e["stand"]["lost"]
               for e in events)
    hub.on_status("/a", 0, "collecting", {"state": "COLLECTING"})
    assert hub.stands["/a"].lost == ""
    hub.on_master({"/a"})
    assert hub.stands["/b"].lost == "its nodes left the ROS master"


def test_faults_keep_the_devices_words_once_each():
    hub = ad.Hub(clock=Clock())
    words = "ALARM:1 hard limit triggered <axis x>"
    for _ in range(3):
        hub.on_progress("/r", 2, words, {"state": "ABORTED"})
    hub.on_status("/r", 2, "run aborted", {"fault": "gimbal: " + words, "state": "ABORTED"})
    faults = hub.stands["/r"].card(False)["faults"]
    assert [f["text"] for f in faults] == [words, "gimbal: " + words, "run aborted"]


# --- The archive view (scripts/accel_dashboard_archive.py) --------------------------------------

def archived_result(serial, u):
    return {
        "model": "joint", "model_label": "joint", "local_gravity": 9.80665,
        "responsivity": {"u": u, "v": 0.99, "w": 1.0},
        "responsivity_std": {"u": 1e-4, "v": 1e-4, "w": 1e-4},
        "angles_deg": {"uv": 90.1, "vw": 89.9, "wu": 90.05},
        "angles_std_deg": {"uv": 0.01, "vw": 0.01, "wu": 0.01},
        "offset": {"u": 0.05, "v": -0.03, "w": 0.08},
        "offset_std": {"u": 0.001, "v": 0.001, "w": 0.001},
        "positions": {"x": 24, "y": 24, "z": 24},
        "certificate": {"serial": serial, "rig": "rig1"},
    }


def test_archive_view_lists_devices_and_their_records_as_stored(tmp_path):
    import accel_archive as aa
    import accel_dashboard_archive as ada
    url = "sqlite:///" + str(tmp_path / "archive.db")
    engine = aa.open_archive(url)
    serial = "<img src=x onerror=alert(1)>"
    for i, u in enumerate((1.01, 1.0102)):
        record, values = aa.make_record(archived_result(serial, u),
                                        when=aa.parse_time("2026-03-0%dT12:00:00Z" % (i + 1)))
        aa.add(engine, record, values)
    engine.dispose()
    view = ada.ArchiveView(url).read()
    assert view["error"] == ""
    assert view["devices"] == [{"serial": serial, "rig": "rig1", "records": 2,
                                "latest": "2026-03-02T12:00:00Z"}]
    history = view["histories"][serial]
    assert [h["values"]["responsivity_u"] for h in history] == [1.01, 1.0102]
    assert history[0]["expanded"]["responsivity_u"] == pytest.approx(2e-4)


def test_archive_view_does_not_migrate_an_old_archive(tmp_path):
    import sqlite3
    import accel_dashboard_archive as ada
    path = tmp_path / "empty.db"
    sqlite3.connect(str(path)).close()
    view = ada.ArchiveView("sqlite:///" + str(path)).read()
    assert "not" in view["error"] and view["devices"] == []
    tables = sqlite3.connect(str(path)).execute("SELECT name FROM sqlite_master").fetchall()
    assert tables == []


def test_archive_view_draws_the_control_chart_of_a_rigs_check_standard(tmp_path):
    import accel_archive as aa
    import accel_dashboard_archive as ada
    url = "sqlite:///" + str(tmp_path / "archive.db")
    engine = aa.open_archive(url)
    serial = "CHK-<b>1</b>"
    # Nine records of the check standard on rig1, |u| with its own standard uncertainty each
    # (expanded U = 2 u at k = 2); the last one shifted far beyond 3U of the others' mean.
    # (All values differ: the archive keeps an identical result once.)
    us = [1.0100, 1.01005, 1.00995, 1.01003, 1.01002, 1.00998, 1.00997, 1.01001, 1.0130]
    stds = [1e-4, 1.2e-4, 1e-4, 1.2e-4, 1e-4, 1.2e-4, 1e-4, 1.2e-4, 3e-4]
    times = ["2026-04-%02dT08:00:00Z" % (i + 1) for i in range(len(us))]
    for u, s, when in zip(us, stds, times):
        result = archived_result(serial, u)
        result["responsivity_std"]["u"] = s
        aa.add(engine, *aa.make_record(result, when=aa.parse_time(when)))
    # The same standard on another rig and another device on rig1: not on rig1's chart.
    other = archived_result(serial, 1.05)
    other["certificate"]["rig"] = "rig2"
    aa.add(engine, *aa.make_record(other, when=aa.parse_time("2026-04-02T09:00:00Z")))
    aa.add(engine, *aa.make_record(archived_result("DUT-7", 1.2),
                                   when=aa.parse_time("2026-04-03T09:00:00Z")))
    engine.dispose()

    view = ada.ArchiveView(url, {"rig1": serial}).read()
    assert view["error"] == ""
    assert list(view["charts"]) == ["rig1"]
    chart = view["charts"]["rig1"]
    assert chart["serial"] == serial
    assert [p["time"] for p in chart["points"]] == times
    # The reference: the weighted mean with weights 1 / u^2 (u = U / 2), computed here.
    weights = [1.0 / s ** 2 for s in stds]
    reference = sum(w * u for w, u in zip(weights, us)) / sum(weights)
    assert chart["reference"]["responsivity_u"] == pytest.approx(reference, rel=1e-12)
    for p, u, s in zip(chart["points"], us, stds):
        assert p["deviation"]["responsivity_u"] == pytest.approx(u - reference, abs=1e-12)
        assert p["expanded"]["responsivity_u"] == pytest.approx(2 * s)
        assert p["deviation"]["responsivity_v"] == pytest.approx(0.0, abs=1e-12)
    # The last point is beyond 3U of the reference; no other point is.
    assert [i for i, (u, s) in enumerate(zip(us, stds))
            if abs(u - reference) > 3 * 2 * s] == [8]
    beyond = [f for f in chart["flags"] if f["rule"] == "beyond_3U"]
    assert [(f["index"], f["parameter"]) for f in beyond] == [(8, "responsivity_u")]
    assert beyond[0]["time"] == times[8]


def test_archive_view_without_check_standards_has_no_chart(tmp_path):
    import accel_archive as aa
    import accel_dashboard_archive as ada
    url = "sqlite:///" + str(tmp_path / "archive.db")
    aa.open_archive(url).dispose()
    view = ada.ArchiveView(url).read()
    assert view["error"] == "" and view["charts"] == {}
    view = ada.ArchiveView(url, {"rig9": "nobody"}).read()
    assert view["charts"]["rig9"]["points"] == [] and view["charts"]["rig9"]["flags"] == []
