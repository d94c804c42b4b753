#!/usr/bin/env python3
"""Mutants drawn by rule (issue 37): `tools/mutants.sh --sample N --seed S`.

The rules of tools/mutant_rules.py are applied to every compiled line of the .cpp files under
src/core (the simulator, the tests' data source, left out), src/io and src/drivers whose object
file the build makes; N of the mutations are drawn with the seed. Each is applied alone to the
scratch copy of tools/mutants.py (same copy, workspace and build lock), built, and run against
every unit binary of the fast tier (tools/fast_tier.py: core_tests, io_tests, drivers_tests,
ros_unit_tests without the slow studies) with --gtest_fail_fast, the binary of the mutated
folder first; the first failure ends the run. Verdicts: caught (with the first failing test),
SURVIVED, equivalent (a survivor listed in tools/mutants_equivalent.txt with the reason), does
not compile (listed, left out of the score). Score = caught / (compiled - equivalent).

The table goes to docs/generated/mutants_sample.md (--table), with the seed and commit.
"""
import collections
import datetime
import glob
import os
import re
import subprocess
import sys
import time

import fast_tier
import mutant_rules
import mutants

FOLDERS = ("src/core", "src/io", "src/drivers")
LEFT_OUT = ("src/core/simulation/",)
EQUIVALENT_LIST = os.path.join(mutants.REPO, "tools", "mutants_equivalent.txt")
FIRST_BINARY = {"src/core": "core_tests", "src/io": "io_tests", "src/drivers": "drivers_tests"}


def built_sources(ws):
    """The sources (paths from the package root) whose object files the workspace's build made."""
    out = set()
    for obj in glob.glob(os.path.join(ws, "build", "**", "*.cpp.o"), recursive=True):
        m = re.search(r"CMakeFiles/[^/]+\.dir/(.+)\.o$", obj)
        if m:
            out.add(m.group(1))
    return out


def candidate_files(source, ws):
    built = built_sources(ws)
    files = []
    for folder in FOLDERS:
        for path in sorted(glob.glob(os.path.join(source, folder, "**", "*.cpp"), recursive=True)):
            rel = os.path.relpath(path, source)
            if rel.startswith(LEFT_OUT) or rel not in built:
                continue
            files.append(rel)
    return files


def all_mutations(source, files):
    out = []
    for rel in files:
        with open(os.path.join(source, rel)) as f:
            out += mutant_rules.mutations_of_text(rel, f.read())
    return out


def read_equivalent(path=EQUIVALENT_LIST):
    """{mutation key: reason} from lines `KEY | file:line | reason` ('#' starts a comment)."""
    out = {}
    if not os.path.exists(path):
        return out
    with open(path) as f:
        for line in f:
            if line.strip() and not line.lstrip().startswith("#"):
                fields = [x.strip() for x in line.split(" | ")]
                out[fields[0]] = fields[-1]
    return out


def binaries_for(path):
    first = next((b for folder, b in FIRST_BINARY.items() if path.startswith(folder + "/")), None)
    return ([first] if first else []) + [b for b in mutants.BINARIES if b != first]


def first_failure(section):
    """The first failing test of one gtest run's output, or what ended it."""
    m = re.search(r"^\[  FAILED  \] (\S+)", section, re.M)
    if m:
        return m.group(1)
    running = re.findall(r"^\[ RUN      \] (\S+)", section, re.M)
    return "crashed in %s" % running[-1] if running else "crashed before any test"


def compile_error(log):
    with open(log, errors="replace") as f:
        for line in f:
            m = re.search(r"error: (.*)", line)
            if m:
                return re.sub(r"\x1b\[[0-9;]*m", "", m.group(1)).strip()[:90]
    return "the build failed"


def run_tier(ws, path, log, tier, timeouts):
    """(verdict, first failing test): every fast-tier binary, that of the mutated folder first."""
    for binary in binaries_for(path):
        ok, why = mutants.run_test(ws, (binary, tier[binary]), log, timeouts[binary],
                                   extra_args=("--gtest_fail_fast",))
        if ok:
            continue
        with open(log, errors="replace") as f:
            section = f.read().split("\n$ ")[-1]
        if why == "timeout":
            return "caught", "%s timed out (%d s)" % (binary, timeouts[binary])
        return "caught", "%s: %s" % (binary, first_failure(section))
    return "SURVIVED", "(the whole fast tier passed)"


def cell(text):
    return text.replace("|", "\\|")


def code(text):
    text = text.strip()
    return "`%s`" % cell(text).replace("`", "'") if text else "(line removed)"


def commit_of(repo):
    head = subprocess.run(["git", "-C", repo, "rev-parse", "--short=12", "HEAD"],
                          stdout=subprocess.PIPE, universal_newlines=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", repo, "status", "--porcelain", "--untracked-files=no"],
                           stdout=subprocess.PIPE, universal_newlines=True).stdout.strip()
    return head + (" (with uncommitted changes)" if dirty else "")


def write_table(path, header, rows, score_line):
    lines = header + ["", "| # | file | line | rule | before | after | verdict | first failing "
                      "test |", "|---|---|---|---|---|---|---|---|"]
    for i, (m, verdict, detail, _) in enumerate(rows, 1):
        lines.append("| %d | %s | %d | %s | %s | %s | %s | %s |" % (
            i, m.path, m.line, m.rule, code(m.before), code(m.after), verdict, cell(detail)))
    lines += ["", score_line]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def baseline(ws, source, binaries, logs):
    """Builds the unmutated copy and runs its fast tier (it must pass; exit 2 if not). Returns
    ({binary: gtest filter}, {binary: timeout s}, {binary: unmutated s}). The lock is held."""
    if not mutants.build(ws, source, binaries, os.path.join(logs, "baseline.build.log")):
        print("[mutants] the unmutated build failed: %s" % os.path.join(logs, "baseline.build.log"))
        sys.exit(2)
    tier = {b: fast_tier.gtest_filter(b) for b in binaries}
    timeouts, tier_s = {}, {}
    for binary in binaries:
        log = os.path.join(logs, "sample.baseline.%s.log" % binary)
        if os.path.exists(log):
            os.remove(log)
        t0 = time.time()
        ok, why = mutants.run_test(ws, (binary, tier[binary]), log, 900)
        seconds = time.time() - t0
        tier_s[binary] = seconds
        if not ok:
            print("[mutants] baseline: the fast tier of %s fails unmutated (%s, log %s): fix it"
                  " first" % (binary, why, log))
            sys.exit(2)
        # A mutant that makes a binary ten times slower than unmutated hung it: caught.
        timeouts[binary] = int(10 * seconds + 30)
        print("[mutants] baseline: %s fast tier passes in %.0f s" % (binary, seconds), flush=True)
    return tier, timeouts, tier_s


def run_one(m, index, ws, source, binaries, logs, tier, timeouts, equivalent, prefix="sample"):
    """Applies one mutation, builds, runs the tier: (verdict, detail, seconds). The lock is held."""
    t0 = time.time()
    log = os.path.join(logs, "%s.%d.%s.log" % (prefix, index, m.key()))
    if os.path.exists(log):
        os.remove(log)
    with mutants.mutated_file(os.path.join(source, m.path), m.apply):
        if not mutants.build(ws, source, binaries, log):
            verdict, detail = "does not compile", compile_error(log)
        else:
            verdict, detail = run_tier(ws, m.path, log, tier, timeouts)
            if verdict == "SURVIVED" and m.key() in equivalent:
                verdict, detail = "equivalent", equivalent[m.key()]
            elif verdict == "caught" and m.key() in equivalent:
                detail += " (listed as equivalent in tools/mutants_equivalent.txt: wrongly)"
    return verdict, detail, time.time() - t0


def run(n, seed, table_path):
    start_all = time.time()
    commit = commit_of(mutants.REPO)  # the code copied now; the checkout may move on meanwhile
    scratch, source, ws, logs = mutants.scratch_layout()
    binaries = list(mutants.BINARIES)
    lock = mutants.BuildLock()
    waited = time.time()
    lock.acquire()
    waited = time.time() - waited  # waits for the build lock are left out of the times below
    tier, timeouts, tier_s = baseline(ws, source, binaries, logs)
    baseline_s = time.time() - start_all - waited

    files = candidate_files(source, ws)
    pool = all_mutations(source, files)
    drawn = mutant_rules.draw(pool, n, seed)
    equivalent = read_equivalent()
    print("[mutants] %d mutations by rule in %d compiled files; %d drawn with seed %d"
          % (len(pool), len(files), len(drawn), seed), flush=True)

    rows = []
    for index, m in enumerate(drawn, 1):
        t0 = time.time()
        lock.turn()
        waited += time.time() - t0
        verdict, detail, seconds = run_one(m, index, ws, source, binaries, logs, tier,
                                           timeouts, equivalent)
        rows.append((m, verdict, detail, seconds))
        print("[mutants] %d/%d %s:%d %s [%s]: %s %s (%.0f s)" % (
            index, len(drawn), m.path, m.line, m.rule, m.key(), verdict, detail, seconds),
            flush=True)
    lock.turn()
    mutants.build(ws, source, binaries, os.path.join(logs, "restore.build.log"))
    lock.release()

    caught = sum(1 for r in rows if r[1] == "caught")
    compiled = sum(1 for r in rows if r[1] != "does not compile")
    equiv = sum(1 for r in rows if r[1] == "equivalent")
    survived = sum(1 for r in rows if r[1] == "SURVIVED")
    denominator = compiled - equiv
    score = 100.0 * caught / denominator if denominator else 0.0
    per_mutant = sum(r[3] for r in rows) / len(rows) if rows else 0.0
    by_rule = collections.Counter(m.rule for m in pool)
    times = {}
    for m, verdict, _, seconds in rows:
        times.setdefault(verdict, []).append(seconds)
    score_line = ("Score: %d caught / (%d compiled - %d equivalent) = %.1f %%; %d survived, %d did"
                  " not compile." % (caught, compiled, equiv, score, survived,
                                     len(rows) - compiled))
    header = [
        "# Mutants drawn by rule: a sample (generated)",
        "",
        "Generated by `bash tools/mutants.sh --sample %d --seed %d` (tools/mutants_sample.py); do"
        " not edit by hand." % (n, seed),
        "",
        "- seed %d, %d mutations drawn from %d made by the rules in %d compiled files (%s)" % (
            seed, len(drawn), len(pool), len(files),
            ", ".join("%s %d" % (r, by_rule[r]) for r in mutant_rules.RULES)),
        "- commit %s, run %s UTC" % (commit,
                                     datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M")),
        "- each mutant built and run against the fast tier (tools/slow_tests.txt left out) of %s"
        " (--gtest_fail_fast); unmutated it takes %s: %.0f s" % (
            ", ".join(binaries), ", ".join("%s %.0f s" % (b, tier_s[b]) for b in binaries),
            sum(tier_s.values())),
        "- wall time (waits for the build lock left out): %.0f s per mutant on average (build and"
        " tests; %s), %.0f s for the unmutated build and fast tier first, %.0f s in all" % (
            per_mutant, ", ".join("%s %.0f s" % (v, sum(t) / len(t)) for v, t in
                                  sorted(times.items())),
            baseline_s, time.time() - start_all - waited),
    ]
    write_table(table_path, header, rows, score_line)
    write_table(os.path.join(scratch, "mutants_sample.md"), header, rows, score_line)
    print(score_line)
    print("[mutants] table: %s" % table_path)
    return 0 if survived == 0 else 1
