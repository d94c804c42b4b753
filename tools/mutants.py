#!/usr/bin/env python3
"""Mutation testing (issue 24): the named mutations of tools/mutants.txt, applied one at a time
to a scratch copy of the repository with its own catkin workspace, built incrementally, and the
tests each names run; a mutation is "caught" when they fail and "SURVIVED" when they pass.
Run it through tools/mutants.sh (which sets up the environment); see docs/development.md."""
import argparse
import contextlib
import fcntl
import os
import shlex
import shutil
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARIES = ("core_tests", "io_tests", "drivers_tests", "ros_unit_tests")


class Mutation:
    def __init__(self, line_number, name, path, pattern, replacement, tests):
        self.line_number = line_number
        self.name = name
        self.path = path
        self.pattern = pattern
        self.replacement = replacement
        self.tests = tests  # [(binary or "rostest", filter or NAME.test)]


def unescape(text):
    return text.replace("\\n", "\n")


def read_list(path):
    mutations, errors = [], []
    with open(path) as f:
        for number, raw in enumerate(f, 1):
            line = raw.rstrip("\n")
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            fields = [x.strip() for x in line.split(" | ")]
            if len(fields) != 5:
                errors.append("%s:%d: expected 5 fields separated by ' | ', found %d"
                              % (path, number, len(fields)))
                continue
            name, file_path, pattern, replacement, tests = fields
            specs = []
            for spec in tests.split(" ; "):
                kind, _, arg = spec.strip().partition(":")
                if kind not in BINARIES + ("rostest",) or not arg:
                    errors.append("%s:%d: %s: bad test spec '%s'" % (path, number, name, spec))
                specs.append((kind, arg))
            mutations.append(Mutation(number, name, file_path, unescape(pattern),
                                      unescape(replacement), specs))
    names = [m.name for m in mutations]
    for n in set(names):
        if names.count(n) > 1:
            errors.append("%s: mutation name '%s' used %d times" % (path, n, names.count(n)))
    return mutations, errors


def check_patterns(mutations, root):
    """The list's errors: a pattern that is not in its file exactly once, or a no-op."""
    errors = []
    for m in mutations:
        path = os.path.join(root, m.path)
        if not os.path.isfile(path):
            errors.append("%s: file %s not found" % (m.name, m.path))
            continue
        with open(path) as f:
            count = f.read().count(m.pattern)
        if count == 0:
            errors.append("%s: pattern not found in %s" % (m.name, m.path))
        elif count > 1:
            errors.append("%s: pattern occurs %d times in %s (must be once)" % (m.name, count, m.path))
        if m.pattern == m.replacement:
            errors.append("%s: the replacement equals the pattern" % m.name)
    return errors


def sync_copy(source):
    """Copies the repository's files (tracked and untracked-not-ignored) into `source`, rewriting
    only files whose content differs, so that make rebuilds only what changed."""
    listing = subprocess.run(["git", "-C", REPO, "ls-files", "-z", "--cached", "--others",
                              "--exclude-standard"], check=True, stdout=subprocess.PIPE).stdout
    changed = 0
    for rel in sorted(set(x for x in listing.decode().split("\0") if x)):
        src = os.path.join(REPO, rel)
        if not os.path.isfile(src) or os.path.islink(src):
            continue
        dst = os.path.join(source, rel)
        with open(src, "rb") as f:
            data = f.read()
        if os.path.isfile(dst):
            with open(dst, "rb") as f:
                if f.read() == data:
                    continue
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        with open(dst, "wb") as f:
            f.write(data)
        shutil.copymode(src, dst)
        changed += 1
    return changed


def scratch_layout():
    """The scratch directory (MUTANTS_DIR), the copy of the checkout in it, its workspace and
    its logs, the copy brought up to date. The copy is named as the checkout, beside the
    workspace as the checkout is beside its own: the compiler then sees the same relative paths,
    and ccache (CCACHE_BASEDIR a common parent) serves the unmutated objects of the main
    workspace."""
    scratch = os.environ["MUTANTS_DIR"]
    source = os.path.join(scratch, os.path.basename(REPO))
    ws = os.path.join(scratch, "ws")
    logs = os.path.join(scratch, "logs")
    os.makedirs(logs, exist_ok=True)
    changed = sync_copy(source)
    print("[mutants] scratch copy %s (%d files updated), workspace %s, logs %s"
          % (source, changed, ws, logs), flush=True)
    return scratch, source, ws, logs


@contextlib.contextmanager
def mutated_file(path, mutate):
    """The file at `path` rewritten as mutate(its text) for the duration of the block, then
    restored byte for byte."""
    with open(path) as f:
        original = f.read()
    try:
        with open(path, "w") as f:
            f.write(mutate(original))
        yield
    finally:
        with open(path, "w") as f:
            f.write(original)


def with_lock(env_name, command):
    lock = os.environ.get(env_name, "")
    return ["flock", lock] + command if lock else command


class BuildLock:
    """ACCEL_BUILD_LOCK held across several mutations (each a build and a short test run), at
    most MUTANTS_LOCK_HOLD_S seconds at a time (default 600), then released for the others: one
    flock per mutation would wait behind every other build on a busy machine."""

    def __init__(self):
        self.path = os.environ.get("ACCEL_BUILD_LOCK", "")
        self.hold_s = float(os.environ.get("MUTANTS_LOCK_HOLD_S", "600"))
        self.fd = None
        self.since = 0.0

    def acquire(self):
        if not self.path or self.fd is not None:
            return
        self.fd = open(self.path, "a")
        fcntl.flock(self.fd, fcntl.LOCK_EX)
        self.since = time.time()

    def release(self):
        if self.fd is not None:
            fcntl.flock(self.fd, fcntl.LOCK_UN)
            self.fd.close()
            self.fd = None

    def turn(self):
        """Between mutations: let the others build once the hold time is used up."""
        if self.fd is not None and time.time() - self.since > self.hold_s:
            self.release()
            time.sleep(2.0)
        self.acquire()


def targets_for(specs, source):
    targets = set()
    for kind, arg in specs:
        if kind == "rostest":
            name = arg[:-5] if arg.endswith(".test") else arg
            if os.path.isfile(os.path.join(source, "test", "ros", name + ".cpp")):
                targets.add("rostest_" + name)
            else:
                targets.add("all")
        else:
            targets.add(kind)
    return sorted(targets)


def build(ws, source, targets, log):
    """Builds with ACCEL_BUILD_LOCK held by the caller (BuildLock)."""
    env = dict(os.environ, ACCEL_WS=ws)
    command = ["nice", "bash", os.path.join(source, "tools", "build.sh")] + targets
    with open(log, "w") as out:
        return subprocess.run(command, env=env, stdout=out, stderr=subprocess.STDOUT).returncode == 0


def run_test(ws, spec, log, timeout, extra_args=()):
    """True when the test passed. A timeout counts as a failure (the mutation hung a test).
    extra_args go to a gtest binary after its filter (e.g. --gtest_fail_fast)."""
    kind, arg = spec
    setup = "source %s >/dev/null 2>&1" % shlex.quote(os.path.join(ws, "devel", "setup.bash"))
    if kind == "rostest":
        run = with_lock("ACCEL_ROSTEST_LOCK", ["rostest", "accel_intrinsics", arg])
    else:
        binary = os.path.join(ws, "devel", "lib", "accel_intrinsics", kind)
        run = [binary, "--gtest_filter=" + arg] + list(extra_args)
    command = ["bash", "-c", setup + " && exec " + " ".join(shlex.quote(x) for x in run)]
    with open(log, "a") as out:
        out.write("$ %s\n" % " ".join(run))
        out.flush()
        try:
            process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                       start_new_session=True)
            code = process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, 9)
            process.wait()
            out.write("\n[mutants] timed out after %d s\n" % timeout)
            return False, "timeout"
    if kind != "rostest":
        # A filter that matches nothing passes vacuously: count it as a list error.
        with open(log) as f:
            text = f.read()
        if "[==========] 0 tests from 0 test suites ran" in text.split("$ ")[-1]:
            return None, "no test matches %s" % arg
    return code == 0, "exit %d" % code


def spec_text(specs):
    return " ; ".join("%s:%s" % s for s in specs)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--list", default=os.path.join(REPO, "tools", "mutants.txt"))
    parser.add_argument("--check", action="store_true",
                        help="only check that every pattern occurs exactly once; no build")
    parser.add_argument("--only", default="", help="comma-separated mutation names")
    parser.add_argument("--skip-baseline", action="store_true",
                        help="do not run the tests unmutated first (they must pass)")
    parser.add_argument("--sample", type=int, default=0,
                        help="instead of the list: N mutations drawn by rule (mutants_sample.py)")
    parser.add_argument("--seed", type=int, default=1, help="the seed of --sample")
    parser.add_argument("--table", default=os.path.join(REPO, "docs", "generated",
                                                        "mutants_sample.md"),
                        help="where --sample writes its table")
    parser.add_argument("--recheck", action="store_true",
                        help="run the survivors of the --table again (mutants_recheck.py)")
    args = parser.parse_args()
    if args.recheck:
        import mutants_recheck
        sys.exit(mutants_recheck.run(args.table))
    if args.sample:
        import mutants_sample
        sys.exit(mutants_sample.run(args.sample, args.seed, args.table))

    mutations, errors = read_list(args.list)
    errors += check_patterns(mutations, REPO)
    if args.only:
        wanted = set(x.strip() for x in args.only.split(",") if x.strip())
        unknown = wanted - set(m.name for m in mutations)
        if unknown:
            errors.append("--only: no mutation named %s" % ", ".join(sorted(unknown)))
        mutations = [m for m in mutations if m.name in wanted]
    for e in errors:
        print("LIST ERROR " + e)
    if args.check or errors:
        print("%d mutations, %d list errors" % (len(mutations), len(errors)))
        sys.exit(1 if errors else 0)

    scratch, source, ws, logs = scratch_layout()
    timeout = int(os.environ.get("MUTANTS_TEST_TIMEOUT", "900"))

    all_specs = sorted(set(s for m in mutations for s in m.tests))
    # MUTANTS_EXTRA_TARGETS: more targets for the unmutated build (e.g. to run other tests there).
    all_targets = sorted(set(targets_for(all_specs, source))
                         | set(os.environ.get("MUTANTS_EXTRA_TARGETS", "").split()))
    print("[mutants] building %s unmutated ..." % " ".join(all_targets), flush=True)
    lock = BuildLock()
    lock.acquire()
    if not build(ws, source, all_targets, os.path.join(logs, "baseline.build.log")):
        print("[mutants] the unmutated build failed: %s" % os.path.join(logs, "baseline.build.log"))
        sys.exit(2)
    if not args.skip_baseline:
        for spec in all_specs:
            log = os.path.join(logs, "baseline.%s.log" % spec[1].replace("/", "_").replace("*", "x"))
            if os.path.exists(log):
                os.remove(log)
            ok, why = run_test(ws, spec, log, timeout)
            if not ok:
                print("[mutants] baseline: %s fails unmutated (%s, log %s): fix it first"
                      % ("%s:%s" % spec, why, log))
                sys.exit(2)
        print("[mutants] baseline: the %d test specs pass unmutated" % len(all_specs), flush=True)

    rows = []
    for index, m in enumerate(mutations, 1):
        lock.turn()
        start = time.time()
        path = os.path.join(source, m.path)
        log = os.path.join(logs, m.name + ".log")
        if os.path.exists(log):
            os.remove(log)
        with mutated_file(path, lambda text: text.replace(m.pattern, m.replacement, 1)):
            if not build(ws, source, targets_for(m.tests, source), log):
                result, caught_by = "BUILD FAILED", "(the mutant does not compile: %s)" % log
            else:
                failing, listed = [], True
                for spec in m.tests:
                    ok, why = run_test(ws, spec, log, timeout)
                    if ok is None:
                        listed = False
                        failing.append("%s:%s (%s)" % (spec[0], spec[1], why))
                    elif not ok:
                        failing.append("%s:%s%s" % (spec[0], spec[1],
                                                    " (timeout)" if why == "timeout" else ""))
                if not listed:
                    result, caught_by = "LIST ERROR", "; ".join(failing)
                elif failing:
                    result, caught_by = "caught", "; ".join(failing)
                else:
                    result, caught_by = "SURVIVED", "(%s passed)" % spec_text(m.tests)
        rows.append((m, result, caught_by))
        print("[mutants] %d/%d %s: %s by %s (%.0f s)" % (index, len(mutations), m.name, result,
                                                      caught_by, time.time() - start), flush=True)
    # Leave the workspace built from the unmutated source.
    lock.turn()
    build(ws, source, all_targets, os.path.join(logs, "restore.build.log"))
    lock.release()

    table = ["| mutation | file | result | caught by |", "|---|---|---|---|"]
    for m, result, caught_by in rows:
        table.append("| %s | %s | %s | %s |" % (m.name, m.path, result,
                                                caught_by.replace("|", "\\|")))
    text = "\n".join(table) + "\n"
    with open(os.path.join(scratch, "mutants_table.md"), "w") as f:
        f.write(text)
    print(text)
    caught = sum(1 for _, r, _ in rows if r == "caught")
    survived = sum(1 for _, r, _ in rows if r == "SURVIVED")
    other = len(rows) - caught - survived
    print("%d caught, %d survived, %d list errors or builds that failed" % (caught, survived, other))
    sys.exit(0 if caught == len(rows) else 1)


if __name__ == "__main__":
    main()
