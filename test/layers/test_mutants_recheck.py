"""The triage of a sample's survivors (tools/mutants_recheck.py, issue 37): a table written by
the --sample writer is read back with every mutation's text intact (pipes, backticks left as
the writer leaves them, removed lines), a survivor is found again in code whose lines moved,
and the rewritten table keeps the first run and scores the triage. No build: the functions
alone. Run by the pytest layers target."""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "tools"))

import mutant_rules as mr  # noqa: E402
import mutants_recheck as rc  # noqa: E402
import mutants_sample as ms  # noqa: E402

SOURCE = ("int f(int a, int b) {\n"
          "  if (a || b) return a + b;\n"
          "  g(a, b);\n"
          "  return a * 2;\n"
          "}\n")


def first_run_table(path):
    pool = mr.mutations_of_text("src/core/x.cpp", SOURCE)
    pick = {"remove": None, "arithmetic": None, "integer": None}
    for m in pool:
        if m.rule in pick and pick[m.rule] is None:
            pick[m.rule] = m
    rows = [(pick["arithmetic"], "caught", "core_tests: A.b", 1.0),
            (pick["remove"], "SURVIVED", "(the whole fast tier passed)", 1.0),
            (pick["integer"], "SURVIVED", "(the whole fast tier passed)", 1.0)]
    ms.write_table(path, ["# header"], rows, "Score: first")
    return pool, rows


def test_the_first_run_reads_back_with_each_mutations_text(tmp_path):
    path = str(tmp_path / "t.md")
    _, rows = first_run_table(path)
    lines, read = rc.read_first_run(path)
    assert lines[0] == "# header" and lines[-1] == "Score: first"
    assert [r["verdict"] for r in read] == ["caught", "SURVIVED", "SURVIVED"]
    for (m, _, _, _), r in zip(rows, read):
        assert (r["path"], r["line"], r["rule"]) == (m.path, m.line, m.rule)
        assert r["before"] == m.before.strip() and r["after"] == m.after.strip()
    assert read[1]["after"] == ""  # the removed statement


def test_a_survivor_is_found_after_its_line_moved_and_not_after_its_text_changed(tmp_path):
    path = str(tmp_path / "t.md")
    first_run_table(path)
    _, read = rc.read_first_run(path)
    moved = mr.mutations_of_text("src/core/x.cpp", "// a new first line\n" + SOURCE)
    found = rc.find(read[2], moved)
    assert found is not None and found.line == read[2]["line"] + 1
    changed = mr.mutations_of_text("src/core/x.cpp", SOURCE.replace("a * 2", "a * 3"))
    assert rc.find(read[2], changed) is None


def test_the_rewritten_table_keeps_the_first_run_and_scores_the_triage(tmp_path):
    path = str(tmp_path / "t.md")
    pool, rows = first_run_table(path)
    lines, read = rc.read_first_run(path)
    triage = [(read[1], rows[1][0], "caught", "core_tests: G.called"),
              (read[2], rows[2][0], "equivalent", "a bound never reached")]
    rc.write(path, lines, read, triage, 12.0, "abc")
    text = open(path).read()
    assert text.count(rc.TRIAGE_HEADING) == 1
    assert "(1 caught in the run + 1 caught on recheck) / (3 compiled - 1 equivalent) = 100.0 %" \
        in text
    # A second recheck replaces the triage and keeps the first run's rows.
    lines2, read2 = rc.read_first_run(path)
    assert lines2 == lines and read2 == read
    rc.write(path, lines2, read2, triage[:1], 1.0, "abc")
    text = open(path).read()
    assert text.count(rc.TRIAGE_HEADING) == 1 and "1 survivors left" not in text
    assert "(1 caught in the run + 1 caught on recheck) / (3 compiled - 0 equivalent) = 66.7 %" \
        in text


def test_a_rows_key_is_the_key_of_its_mutation(tmp_path):
    path = str(tmp_path / "t.md")
    _, rows = first_run_table(path)
    _, read = rc.read_first_run(path)
    for (m, _, _, _), r in zip(rows, read):
        assert rc.row_key(r) == m.key()
