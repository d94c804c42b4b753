"""The documentation is true (docs/design.md section 16): README and docs/ within their lengths,
mkdocs builds them strictly with every page in the nav, docs/nodes.md lists exactly the
parameters the code reads, no file refers to a path outside the package, the commands marked
runnable run, and every plotting script is reached by a documented command.

Run by tools/test.sh (catkin run_tests, pytest-docs.xml); alone, with the workspace sourced:
    /usr/bin/python3 -m pytest -q test/docs
"""
import os
import re
import shutil
import subprocess
import tempfile

import pytest

import docs_check as dc

PKG = dc.PACKAGE


def read(path):
    with open(os.path.join(PKG, path)) as f:
        return f.read()


# ---- README and page lengths --------------------------------------------------------------

README_FIRST_LINES = [
    "```bash",
    "bash tools/demo.sh   # as root on Debian 12: install, build, run the simulated test stand end to end",
    "bash tools/test.sh   # as root on Debian 12: install, build, run every test (\"N passed, N failed\")",
    "```",
]


def test_readme_starts_with_the_two_commands():
    assert read("README.md").splitlines()[:4] == README_FIRST_LINES


def test_lengths():
    too_long = []
    if len(read("README.md").splitlines()) > 200:
        too_long.append("README.md: %d lines (at most 200)" % len(read("README.md").splitlines()))
    for page in dc.markdown_files()[1:]:
        n = len(read(page).splitlines())
        if page != "docs/design.md" and n > 400:
            too_long.append("%s: %d lines (at most 400)" % (page, n))
    assert not too_long, "\n".join(too_long)


def test_readme_has_no_dated_figures_issue_numbers_or_hashes():
    text = read("README.md")
    found = []
    for n, line in enumerate(text.splitlines(), 1):
        if re.search(r"\b20\d\d-\d\d-\d\d\b", line):
            found.append("README.md:%d: a date" % n)
        if re.search(r"\bissue \d+", line, re.I):
            found.append("README.md:%d: an issue number" % n)
        if re.search(r"\bcommit [0-9a-f]{7,40}\b", line):
            found.append("README.md:%d: a commit hash" % n)
    assert not found, "\n".join(found)


# ---- mkdocs -----------------------------------------------------------------------------

def nav_pages():
    pages = []
    for line in read("mkdocs.yml").splitlines():
        m = re.match(r"\s*-\s*(?:[^:]+:\s*)?([\w./-]+\.md)\s*$", line)
        if m:
            pages.append(m.group(1))
    return pages


def test_every_docs_page_is_in_the_nav_and_every_nav_entry_exists():
    on_disk = {f for f in os.listdir(os.path.join(PKG, "docs")) if f.endswith(".md")}
    nav = set(nav_pages())
    assert on_disk - nav == set(), "pages outside the nav of mkdocs.yml: %s" % sorted(on_disk - nav)
    assert nav - on_disk == set(), "nav entries without a page: %s" % sorted(nav - on_disk)


def test_mkdocs_build_strict():
    mkdocs = shutil.which("mkdocs") or "/usr/bin/mkdocs"
    assert os.path.exists(mkdocs), "mkdocs is missing: apt-get install mkdocs (tools/install_deps.sh)"
    with tempfile.TemporaryDirectory() as out:
        r = subprocess.run([mkdocs, "build", "--strict", "--site-dir", os.path.join(out, "site")],
                           cwd=PKG, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, "mkdocs build --strict failed:\n" + r.stdout + r.stderr
        # mkdocs 1.4 only logs pages outside the nav (INFO); the test above fails on them.
        assert "WARNING" not in r.stderr, r.stderr


# ---- docs/nodes.md against the code -------------------------------------------------------

def test_nodes_md_lists_exactly_the_parameters_the_code_reads():
    read_params, problems = dc.parameters_read()
    differences = problems + dc.compare_parameters(read_params,
                                                   dc.parameters_documented(read("docs/nodes.md")))
    assert not differences, "\n" + "\n".join(differences)
    # The parser finds something in every node (a broken parser would find nothing at all).
    assert all(read_params[node] for node in dc.NODE_SOURCES), read_params


def test_self_test_a_parameter_read_but_not_documented_is_named():
    fake = 'void f(const ros::NodeHandle& pnh) { read_param(pnh, "fake_param_for_self_test", &x); }'
    read_params, _ = dc.parameters_read(
        extra_sources={"src/ros/calibration_options.cpp": read("src/ros/calibration_options.cpp")
                       + "\n" + fake})
    lines = dc.compare_parameters(read_params, dc.parameters_documented(read("docs/nodes.md")))
    assert len(lines) == 1, lines
    assert "'## calibration'" in lines[0] and "`fake_param_for_self_test`" in lines[0], lines
    assert "src/ros/calibration_options.cpp:" in lines[0], lines


def test_self_test_a_documented_row_removed_or_unread_is_named():
    nodes_md = read("docs/nodes.md")
    read_params, _ = dc.parameters_read()
    without = "\n".join(l for l in nodes_md.splitlines() if not l.startswith("| `tick_hz` |"))
    lines = dc.compare_parameters(read_params, dc.parameters_documented(without))
    assert lines == [l for l in lines if "'## gimbal_controller'" in l and "`tick_hz`" in l] \
        and len(lines) == 1, lines
    extra = nodes_md.replace("| `rate_hz` | double | 200 |",
                             "| `never_read_here` | int | 0 | | fake |\n| `rate_hz` | double | 200 |")
    lines = dc.compare_parameters(read_params, dc.parameters_documented(extra))
    assert len(lines) == 1 and "`never_read_here`" in lines[0] and "never reads" in lines[0], lines
    no_default = nodes_md.replace("| `poll_hz` | double | 200 |", "| `poll_hz` | double |  |")
    lines = dc.compare_parameters(read_params, dc.parameters_documented(no_default))
    assert len(lines) == 1 and "`poll_hz`" in lines[0] and "no default" in lines[0], lines


def test_self_test_the_parser_sees_every_way_of_reading():
    src = """
    void g(const ros::NodeHandle& pnh, ros::NodeHandle& nh2) {
      read_param(pnh, "a", &a);            // a helper
      read_vector3(pnh, "b", &b);
      std::string m = pnh.param<std::string>("c", "x");
      pnh.getParam("d", d);
      if (!getPrivateNodeHandle().hasParam("e")) {}
      const ros::NodeHandle sub(pnh, "sub");
      read_param(sub, "f", &f);
      const ros::NodeHandle dn(pnh, driver);
      const ros::NodeHandle ph(dn, key);
      read_param(ph, "sign", &s);
      read_protocol(pnh);
      param_name(pnh, "not_a_read");
      // read_param(pnh, "commented_out", &z);
    }"""
    names = {n for n, _ in dc.reads_in_source(src, {"read_protocol": ["steps"]})}
    assert names == {"a", "b", "c", "d", "e", "sub/f", "<driver>/phases/<p>/sign", "steps"}, names


def test_self_test_a_new_file_that_reads_parameters_is_not_silently_ignored():
    _, problems = dc.parameters_read(
        extra_sources={"src/ros/new_driver_options.cpp":
                       'void f(const ros::NodeHandle& pnh) { read_param(pnh, "baud", &b); }'})
    assert len(problems) == 1 and "src/ros/new_driver_options.cpp" in problems[0], problems


# ---- paths outside the package ------------------------------------------------------------

def test_no_file_refers_to_a_path_outside_the_package():
    texts = {}
    for f in dc.package_files():
        try:
            texts[f] = read(f)
        except (UnicodeDecodeError, IsADirectoryError, FileNotFoundError):
            pass
    assert len(texts) > 100, "found too few files to check: %d" % len(texts)
    found = dc.outside_references(texts)
    assert not found, "\n" + "\n".join("%s:%d: %s" % f for f in found)


def test_self_test_outside_references_are_found():
    # The outside path is joined here so that this file itself cites nothing outside the package.
    outside = "../" + "shared/" + "DESIGN" + ".md"
    found = dc.outside_references({
        "a.cpp": "// see " + outside + " section 2\nint x;\n",
        "b.md": "cites docs/design.md section 3 only\n",
        "c.sh": "cp /work/main/x .\n"})
    assert [(p, n) for p, n, _ in found] == [("a.cpp", 1), ("a.cpp", 1), ("c.sh", 1)], found


# ---- commands marked runnable -------------------------------------------------------------

def marked_blocks():
    out = []
    for page in dc.markdown_files():
        out += [(page, line, code) for line, code in dc.runnable_blocks(read(page))]
    return out


def test_the_marked_set_is_small():
    blocks = marked_blocks()
    assert 1 <= len(blocks) <= 10, blocks


def test_self_test_only_marked_bash_blocks_are_taken():
    text = "x\n<!-- runnable -->\n```bash\necho one\n```\n```bash\necho two\n```\n" \
           "<!-- runnable -->\ntext between\n```bash\necho three\n```\n"
    assert dc.runnable_blocks(text) == [(4, "echo one")]


@pytest.mark.parametrize("page,line,code", marked_blocks(),
                         ids=["%s:%d" % (p, l) for p, l, _ in marked_blocks()])
def test_marked_command_runs(page, line, code):
    found = subprocess.run(["rospack", "find", "accel_intrinsics"], capture_output=True, text=True)
    assert found.returncode == 0, ("rospack does not find accel_intrinsics: run with the workspace "
                                   "sourced (source devel/setup.bash)")
    env = dict(os.environ)
    env["PATH"] = "/usr/bin:" + env.get("PATH", "")
    with tempfile.TemporaryDirectory() as tmp:
        env["TMPDIR"] = tmp
        r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", code], cwd=PKG, env=env,
                           capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, "%s:%d exited %d:\n%s\n--- stdout\n%s\n--- stderr\n%s" % (
        page, line, r.returncode, code, r.stdout[-3000:], r.stderr[-3000:])


# ---- plotting scripts ---------------------------------------------------------------------

# A plotting script run by a tool: (the tool, its option, the file that runs the script).
PLOTTED_BY = {
    "plot_allan": ("noise_report", "--plot", "src/ros/noise_report.cpp"),
    "compare_results_plot": ("compare_results", "--plot", "src/ros/compare_results.cpp"),
    "certificate_report": ("offline_fit", "--report", "src/ros/offline_fit.cpp"),
    "accel_history.py": ("history", "--plot", "scripts/history"),
}


def code_lines():
    lines = []
    for page in dc.markdown_files():
        inside = False
        for line in read(page).splitlines():
            if line.strip().startswith("```"):
                inside = not inside
                continue
            if inside:
                if lines and lines[-1].endswith("\\"):
                    lines[-1] = lines[-1][:-1] + " " + line.strip()  # a continued command
                else:
                    lines.append(line)
    return lines


def test_every_plotting_script_is_reached_by_a_documented_command():
    scripts = sorted(f for f in os.listdir(os.path.join(PKG, "scripts"))
                     if os.path.isfile(os.path.join(PKG, "scripts", f))
                     and "matplotlib" in read("scripts/" + f))
    assert scripts, "no plotting script found"
    lines, missing = code_lines(), []
    for script in scripts:
        name = script[:-3] if script.endswith(".py") else script
        if any(re.search(r"\b%s\b" % re.escape(name), l) for l in lines):
            continue
        if script in PLOTTED_BY:
            tool, option, caller = PLOTTED_BY[script]
            runs_it = name in read(caller)
            if runs_it and any(tool in l and option in l for l in lines):
                continue
        missing.append(script)
    assert not missing, "plotting scripts no documented command reaches: %s" % missing
