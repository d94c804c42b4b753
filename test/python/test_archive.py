"""The lab archive (scripts/accel_archive.py, scripts/archive, scripts/history) on SQLite and on a
real PostgreSQL server (conftest.py): records, deduplication, concurrent writers, a writer killed
inside its transaction, the schema upgrade from the first revision, passwords never printed."""
import copy
import datetime
import json
import os
import re
import signal
import subprocess
import sys

import pytest
import sqlalchemy as sa

from conftest import SCRIPTS
import accel_archive as aa

HERE = os.path.dirname(os.path.realpath(__file__))
REAL_RESULT = os.path.join(HERE, "data", "six_position_result.json")
PYTHON = "/usr/bin/python3"


def synthetic_result(serial="DUT-1", scale=1.0, stamp=None, rig=None):
    """A result with the keys offline_fit writes (no budget: U = 2 * std)."""
    result = {
        "model": "joint", "model_label": "joint", "local_gravity": 9.80665,
        "responsivity": {"u": 1.01 * scale, "v": 0.99 * scale, "w": 1.0 * scale},
        "responsivity_std": {"u": 1e-4, "v": 1e-4, "w": 1e-4},
        "angles_deg": {"uv": 90.1, "vw": 89.9, "wu": 90.05},
        "angles_std_deg": {"uv": 0.01, "vw": 0.01, "wu": 0.01},
        "offset": {"u": 0.05, "v": -0.03, "w": 0.08},
        "offset_std": {"u": 0.001, "v": 0.001, "w": 0.001},
        "positions": {"x": 24, "y": 24, "z": 24},
        "certificate": {"serial": serial},
    }
    if rig:
        result["certificate"]["rig"] = rig
    if stamp is not None:
        result["stamp"] = stamp
    return result


def write_json(path, document):
    with open(str(path), "w") as f:
        json.dump(document, f)
    return str(path)


def run_archive(*argv, env=None):
    return subprocess.run([PYTHON, os.path.join(SCRIPTS, "archive")] + [str(a) for a in argv],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          universal_newlines=True, timeout=300, env=env)


def run_history(*argv):
    return subprocess.run([PYTHON, os.path.join(SCRIPTS, "history")] + [str(a) for a in argv],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          universal_newlines=True, timeout=300)


def count(url, table):
    engine = aa.create_engine(url)
    with engine.connect() as connection:
        n = connection.execute(sa.text("SELECT COUNT(*) FROM %s" % table)).scalar_one()
    engine.dispose()
    return n


# --- Results into records (no database) ----------------------------------------------------------

def test_real_result_uses_the_budget_expanded_uncertainties():
    result = aa.load_result(REAL_RESULT)
    values = aa.parameter_values(result)
    expanded = result["uncertainty_budget"]["expanded"]
    assert values["responsivity_u"] == (result["responsivity"]["u"],
                                        expanded["responsivity"]["u"], expanded["k"])
    assert values["angle_vw"][1] == expanded["angles_deg"]["vw"]
    assert values["offset_w"][1] == expanded["offset"]["w"]
    record, _ = aa.make_record(result)
    assert record["device_serial"] == result["certificate"]["serial"]
    # six known orientations, no gimbal phase
    assert record["method"] == "positions"


def test_without_budget_expanded_is_two_standard_uncertainties():
    values = aa.parameter_values(synthetic_result())
    assert values["responsivity_v"] == (0.99, 2e-4, 2.0)
    assert values["angle_uv"] == (90.1, 0.02, 2.0)


def test_method_serial_rig_and_time():
    result = synthetic_result()
    assert aa.result_method(result) == "gimbal"
    assert aa.result_method(dict(result, method="tumble")) == "tumble"
    table = "phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w,f_x,f_y,f_z\n"
    assert aa.result_method(result, table) == "positions"
    with pytest.raises(aa.ArchiveError, match="unknown method"):
        aa.result_method(dict(result, method="guess"))
    with pytest.raises(aa.ArchiveError, match="differs"):
        aa.make_record(result, device="OTHER")
    no_serial = synthetic_result()
    del no_serial["certificate"]
    with pytest.raises(aa.ArchiveError, match="no device serial"):
        aa.make_record(no_serial)
    record, _ = aa.make_record(no_serial, device="D9", rig="bench")
    assert (record["device_serial"], record["rig"]) == ("D9", "bench")
    # the result's own stamp is its time; a simulated clock's stamp (100 s) is not a date
    stamped, _ = aa.make_record(synthetic_result(stamp=1767225600.0))
    assert stamped["time"] == datetime.datetime(2026, 1, 1)
    simulated, _ = aa.make_record(synthetic_result(stamp=100.0))
    assert simulated["time"].year >= 2026
    assert aa.parse_time("2026-03-01T12:00:00+02:00") == datetime.datetime(2026, 3, 1, 10)
    with pytest.raises(aa.ArchiveError, match="ISO 8601"):
        aa.parse_time("yesterday")


def test_result_failing_the_quality_gate_is_refused():
    failed = dict(synthetic_result(), quality={"pass": False, "reasons": ["reduced chi2 40"]})
    with pytest.raises(aa.ArchiveError, match="quality gate \\(reduced chi2 40\\)"):
        aa.make_record(failed)
    passed = dict(synthetic_result(), quality={"pass": True, "reasons": []})
    assert aa.make_record(passed)[0]["device_serial"] == "DUT-1"


def test_bad_result_is_a_clear_error(tmp_path):
    bad = synthetic_result()
    del bad["angles_deg"]["vw"]
    out = run_archive("--archive", "sqlite:///" + str(tmp_path / "a.db"), "add",
                      write_json(tmp_path / "bad.json", bad))
    assert out.returncode == 1
    assert "angles_deg.vw" in out.stderr


# --- Both backends -------------------------------------------------------------------------------

def test_add_is_deduplicated_and_history_reads_it(archive_url, tmp_path):
    result = write_json(tmp_path / "r.json", synthetic_result())
    first = run_archive("--archive", archive_url, "add", result, "--rig", "bench",
                        "--time", "2026-01-01")
    assert first.returncode == 0, first.stderr
    assert "added record" in first.stdout
    again = run_archive("--archive", archive_url, "add", result, "--rig", "bench",
                        "--time", "2026-01-01")
    assert again.returncode == 0, again.stderr
    assert "already archived" in again.stdout
    assert count(archive_url, "records") == 1
    assert count(archive_url, "parameters") == 9
    # the same input with another result (another fit of the same data) is another record
    changed = write_json(tmp_path / "r2.json", synthetic_result(scale=1.001))
    assert run_archive("--archive", archive_url, "add", changed, "--time", "2026-02-01",
                       "--rig", "bench").returncode == 0
    assert count(archive_url, "records") == 2
    out = run_history("DUT-1", "--archive", archive_url, "--json", tmp_path / "h.json",
                      "--plot", tmp_path / "h.png")
    assert out.returncode == 0, out.stderr
    assert os.path.getsize(str(tmp_path / "h.png")) > 10000
    with open(str(tmp_path / "h.json")) as f:
        doc = json.load(f)
    assert [r["time"] for r in doc["records"]] == ["2026-01-01T00:00:00Z", "2026-02-01T00:00:00Z"]
    assert doc["records"][1]["values"]["responsivity_u"] == pytest.approx(1.01 * 1.001)
    assert doc["records"][0]["expanded"]["offset_v"] == pytest.approx(0.002)
    # E_n of the change: (1.01*1.001 - 1.01) / sqrt(2) / 2e-4
    assert doc["E_n_consecutive"]["responsivity_u"][0] == pytest.approx(
        1.01e-3 / (2 ** 0.5 * 2e-4))
    assert set(doc["drift"]) == set(aa.PARAMETER_NAMES)
    # --json -: stdout is the JSON alone
    piped = run_history("DUT-1", "--archive", archive_url, "--json", "-")
    assert json.loads(piped.stdout)["records"] == doc["records"]
    # the whole result and the position table are kept
    engine = aa.open_archive(archive_url)
    stored, table = aa.fetch_result(engine, doc["records"][0]["id"])
    engine.dispose()
    assert stored == synthetic_result() and table is None


def test_real_result_with_position_table(archive_url, tmp_path):
    table = os.path.join(os.path.dirname(os.path.dirname(HERE)), "docs", "examples",
                         "six_position.csv")
    out = run_archive("--archive", archive_url, "add", REAL_RESULT, "--positions", table,
                      "--input", table, "--rig", "bench")
    assert out.returncode == 0, out.stderr
    engine = aa.open_archive(archive_url)
    rows = aa.fetch_records(engine, device="SN 000123")
    stored, stored_table = aa.fetch_result(engine, rows[0]["id"])
    engine.dispose()
    with open(table) as f:
        assert stored_table == f.read()
    assert rows[0]["input_sha256"] == aa.sha256_files([table])
    assert rows[0]["method"] == "positions"
    assert stored == aa.load_result(REAL_RESULT)
    # the certificate with the device's history page (a third page); a draft: the stored result
    # has the template's certificate block and the standard g (refused otherwise)
    pdf = str(tmp_path / "certificate.pdf")
    out = subprocess.run([PYTHON, os.path.join(SCRIPTS, "certificate_report"), "--out", pdf,
                          "--draft", "--history-archive", archive_url, REAL_RESULT],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True)
    assert out.returncode == 0, out.stderr
    info = subprocess.run(["pdfinfo", pdf], stdout=subprocess.PIPE, universal_newlines=True)
    assert re.search(r"^Pages:\s+3$", info.stdout, re.M), info.stdout


def test_concurrent_writers_lose_nothing(archive_url, tmp_path):
    # 6 processes start together on an archive that does not exist yet (all of them create or
    # upgrade the schema), each adds 4 results of its own and 2 that every process adds.
    shared = [write_json(tmp_path / ("shared%d.json" % i), synthetic_result(serial="SHARED%d" % i))
              for i in range(2)]
    processes = []
    for p in range(6):
        files = [write_json(tmp_path / ("p%d_%d.json" % (p, i)),
                            synthetic_result(serial="P%d" % p, scale=1.0 + 1e-3 * i))
                 for i in range(4)]
        script = ("import subprocess, sys\n"
                  "for f in sys.argv[2:]:\n"
                  "    r = subprocess.run([%r, %r, '--archive', sys.argv[1], 'add', f])\n"
                  "    if r.returncode: sys.exit(r.returncode)\n"
                  % (PYTHON, os.path.join(SCRIPTS, "archive")))
        processes.append(subprocess.Popen([PYTHON, "-c", script, archive_url] + files + shared,
                                          stdout=subprocess.DEVNULL))
    assert [p.wait(timeout=600) for p in processes] == [0] * 6
    assert count(archive_url, "records") == 6 * 4 + 2
    assert count(archive_url, "parameters") == 9 * (6 * 4 + 2)


KILLED_WRITER = """
import sys, time
sys.path.insert(0, sys.argv[1])
import accel_archive as aa
engine = aa.open_archive(sys.argv[2])
record, values = aa.make_record(aa.load_result(sys.argv[3]))
with engine.begin() as connection:
    aa.insert_record(connection, record, values)
    print("inserted", flush=True)
    time.sleep(600)
"""


def test_killed_writer_leaves_nothing_half_written(archive_url, tmp_path):
    result = write_json(tmp_path / "r.json", synthetic_result(serial="KILLED"))
    writer = subprocess.Popen([PYTHON, "-c", KILLED_WRITER, SCRIPTS, archive_url, result],
                              stdout=subprocess.PIPE, universal_newlines=True)
    assert writer.stdout.readline().strip() == "inserted"
    writer.send_signal(signal.SIGKILL)
    writer.wait(timeout=60)
    assert count(archive_url, "records") == 0
    assert count(archive_url, "parameters") == 0
    # the archive is usable and the same result goes in once
    out = run_archive("--archive", archive_url, "add", result)
    assert out.returncode == 0, out.stderr
    assert count(archive_url, "records") == 1
    assert count(archive_url, "parameters") == 9


def test_schema_upgrade_from_the_first_revision(archive_url):
    engine = aa.create_engine(archive_url)
    aa.upgrade(engine, "0001")
    with engine.connect() as connection:
        assert aa.current_revision(connection) == "0001"
    # a record as revision 0001 stored it (no parameter rows yet)
    record, _ = aa.make_record(synthetic_result(serial="OLD"), when=datetime.datetime(2025, 6, 1))
    with engine.begin() as connection:
        connection.execute(sa.text(
            "INSERT INTO records (device_serial, rig, time, method, local_gravity, model, "
            "result_json, position_table, input_sha256, result_sha256, added_at, added_by) "
            "VALUES (:device_serial, :rig, :time, :method, :local_gravity, :model, :result_json, "
            ":position_table, :input_sha256, :result_sha256, :added_at, :added_by)"), record)
    engine.dispose()
    engine = aa.open_archive(archive_url)
    with engine.connect() as connection:
        assert aa.current_revision(connection) == aa.head_revision() == "0002"
    rows = aa.fetch_records(engine, device="OLD")
    engine.dispose()
    assert len(rows) == 1
    assert rows[0]["values"]["responsivity_u"] == 1.01
    assert rows[0]["expanded"]["angle_wu"] == pytest.approx(0.02)


def test_password_never_printed(archive_url, tmp_path):
    result = write_json(tmp_path / "r.json", synthetic_result())
    secret = "s3cretPw"
    if archive_url.startswith("postgresql"):
        # the test server trusts its socket: the password is accepted and must not show
        url = archive_url.replace("postgres@", "postgres:%s@" % secret)
        out = run_archive("--archive", url, "add", result)
        assert out.returncode == 0, out.stderr
        assert "***" in out.stdout
    # a server that is not there: the error names the URL without its password
    unreachable = "postgresql://labuser:%s@127.0.0.1:1/archive" % secret
    out = run_archive("--archive", unreachable, "add", result)
    assert out.returncode == 1
    assert "labuser" in out.stderr
    for stream in (out.stdout, out.stderr):
        assert secret not in stream
    assert secret not in aa.display_url(unreachable)


def test_history_of_unknown_device_fails(archive_url):
    out = run_history("NOBODY", "--archive", archive_url)
    assert out.returncode == 1
    assert "no record of device 'NOBODY'" in out.stderr


def test_check_standard_chart_and_rigs(archive_url, tmp_path):
    for day, scale in enumerate([1.0, 1.00005, 0.99995, 1.00001, 1.001]):
        r = synthetic_result(serial="CHECK-1", scale=scale)
        path = write_json(tmp_path / ("c%d.json" % day), r)
        assert run_archive("--archive", archive_url, "add", path, "--rig", "bench",
                           "--time", "2026-01-%02d" % (day + 1)).returncode == 0
    other = write_json(tmp_path / "other.json", synthetic_result(serial="CHECK-1", scale=1.002))
    assert run_archive("--archive", archive_url, "add", other, "--rig", "stand2",
                       "--time", "2026-01-03").returncode == 0
    out = run_history("--rig", "bench", "--check-standard", "CHECK-1", "--archive", archive_url,
                      "--json", tmp_path / "chart.json", "--plot", tmp_path / "chart.png")
    assert out.returncode == 0, out.stderr
    with open(str(tmp_path / "chart.json")) as f:
        chart = json.load(f)
    assert len(chart["points"]) == 5  # stand2's record is not on this chart
    # the last point is 1e-3 * 1.01 above the others (0.8e-3 above their mean with it), U = 2e-4: beyond 3U
    assert {(f["time"], f["parameter"], f["rule"]) for f in chart["flags"]
            if f["rule"] == "beyond_3U"} >= {("2026-01-05T00:00:00Z", "responsivity_u",
                                              "beyond_3U")}
    assert os.path.getsize(str(tmp_path / "chart.png")) > 10000
    out = run_history("CHECK-1", "--rigs", "--archive", archive_url, "--json", tmp_path / "r.json")
    assert out.returncode == 0, out.stderr
    with open(str(tmp_path / "r.json")) as f:
        rigs = json.load(f)
    assert set(rigs["rigs"]) == {"bench", "stand2"}
    pair = rigs["E_n_between_rigs"][0]
    assert pair["E_n"]["responsivity_u"] == pytest.approx(
        (1.01 * 1.001 - 1.01 * 1.002) / (2 ** 0.5 * 2e-4))
    assert not pair["consistent"]
