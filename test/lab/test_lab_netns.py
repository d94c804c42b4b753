"""A small lab inside this machine (docs/design.md section 14, issue 26): one network namespace per PC
-- the master with the supervisor, two stand PCs, the archive server -- cabled with veth pairs to a
switch (a bridge in a namespace of its own) on the private subnet 10.213.0.0/24, which the test
creates and removes itself; nothing else of the machine's network is touched. Every process gets
ROS_MASTER_URI and ROS_IP as a lab PC would.

  master   10.213.0.1   roscore, supervise stand1 stand2
  stand1   10.213.0.11  launch/lab_stand.launch (gimbal, accelerometer, calibration, its clock)
  stand2   10.213.0.12  the same, another simulated device
  archive  10.213.0.20  PostgreSQL (the lab archive; SQLite on the master when none is installed)

Each stand PC runs its launch under a loop that starts it again when it ends (what systemd's
Restart=always does on a real PC). The supervisor starts both runs; meanwhile:
  1. stand1's cable is pulled at the switch for 8 s, then plugged in again;
  2. stand2's PC loses power (every process in its namespace is killed) and boots again;
  3. the master restarts (roscore killed and started again: a new /run_id).
Then both runs must end with complete position tables fitted within 5 standard uncertainties of
the simulated truth, both results in the archive on the server, and every fault named: by the
supervisor (silence, the link back, restarted nodes, the master restarted) and by the stands'
logs (master_watch, the calibration node continuing from its checkpoint).

Skipped, with the reason, where namespaces cannot be made (not root, no CAP_NET_ADMIN, no veth)
or the stand is not built. Takes about two to three minutes.
"""
import json
import os
import pwd
import re
import shutil
import signal
import subprocess
import tempfile
import time

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
SUBNET = "10.213.0"
ADDRESS = {"master": SUBNET + ".1", "stand1": SUBNET + ".11", "stand2": SUBNET + ".12",
           "archive": SUBNET + ".20"}
MASTER_URI = "http://%s:11311" % ADDRESS["master"]
STEPS = 6
TIME_SCALE = 1.0
DEVICES = {"stand1": ("LAB-A", "simulated_device.yaml", 11),
           "stand2": ("LAB-B", "simulated_device_b.yaml", 12)}


def run(argv, timeout=60, check=True, env=None):
    out = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         universal_newlines=True, timeout=timeout, env=env)
    if check and out.returncode != 0:
        raise RuntimeError("%s: exit %d: %s" % (" ".join(argv), out.returncode, out.stdout.strip()))
    return out


def stand_built():
    if not shutil.which("roslaunch") or not shutil.which("roscore") or not shutil.which("ip"):
        return "no ROS tools (roscore, roslaunch) or no iproute2 (ip) on PATH"
    found = run(["rospack", "find", "accel_intrinsics"], check=False)
    if found.returncode != 0:
        return "accel_intrinsics is not in a sourced workspace (ROS_PACKAGE_PATH)"
    libexec = run(["catkin_find", "--first-only", "--libexec", "accel_intrinsics"],
                  check=False).stdout.strip()
    missing = [n for n in ("calibration", "accelerometer", "gimbal_controller", "sim_clock")
               if not os.path.exists(os.path.join(libexec, n))]
    return "stand nodes not built: %s" % ", ".join(missing) if missing else None


class Lab:
    """The namespaces, the cabling and the processes; `close` removes all of it."""

    def __init__(self, directory):
        self.directory = directory
        tag = "acl%04x" % (os.getpid() & 0xffff)
        self.tag = tag
        self.ns = {pc: "%s_%s" % (tag, pc) for pc in ("switch", "master", "stand1", "stand2",
                                                        "archive")}
        self.created = []
        self.processes = {}
        self.logs = {}
        self.postgres = None
        self.wall_epoch_s = time.time()

    # ---- network ------------------------------------------------------------------------------
    def create(self):
        """Returns None, or why namespaces cannot be made here."""
        if os.geteuid() != 0:
            return "not root: `ip netns add` needs CAP_NET_ADMIN (run the suite as root)"
        for pc, name in self.ns.items():
            out = run(["ip", "netns", "add", name], check=False)
            if out.returncode != 0:
                return "`ip netns add` failed (no CAP_NET_ADMIN?): %s" % out.stdout.strip()
            self.created.append(name)
            run(["ip", "-n", name, "link", "set", "lo", "up"])
        switch = self.ns["switch"]
        out = run(["ip", "-n", switch, "link", "add", "br0", "type", "bridge"], check=False)
        if out.returncode != 0:
            return "cannot make a bridge in a namespace: %s" % out.stdout.strip()
        run(["ip", "-n", switch, "link", "set", "br0", "up"])
        for index, pc in enumerate(("master", "stand1", "stand2", "archive")):
            a, b = "%sa%d" % (self.tag, index), "%sb%d" % (self.tag, index)
            out = run(["ip", "link", "add", a, "type", "veth", "peer", "name", b], check=False)
            if out.returncode != 0:
                return "cannot make veth pairs: %s" % out.stdout.strip()
            run(["ip", "link", "set", a, "netns", switch])
            run(["ip", "link", "set", b, "netns", self.ns[pc]])
            port = "to_" + pc  # the switch port of the PC's cable
            run(["ip", "-n", switch, "link", "set", "dev", a, "name", port])
            run(["ip", "-n", switch, "link", "set", "dev", port, "master", "br0"])
            run(["ip", "-n", switch, "link", "set", "dev", port, "up"])
            run(["ip", "-n", self.ns[pc], "link", "set", b, "name", "eth0"])
            run(["ip", "-n", self.ns[pc], "addr", "add", ADDRESS[pc] + "/24", "dev", "eth0"])
            run(["ip", "-n", self.ns[pc], "link", "set", "eth0", "up"])
        return None

    def cable(self, pc, plugged):
        """The PC's cable at the switch: plugged in or pulled (the link goes down both ends)."""
        run(["ip", "-n", self.ns["switch"], "link", "set", "dev", "to_" + pc,
             "up" if plugged else "down"])

    # ---- processes ----------------------------------------------------------------------------
    def env(self, pc):
        env = dict(os.environ)
        env.pop("ROS_HOSTNAME", None)
        home = os.path.join(self.directory, pc, "ros_home")
        os.makedirs(home, exist_ok=True)
        env.update(ROS_MASTER_URI=MASTER_URI, ROS_IP=ADDRESS[pc], ROS_HOME=home,
                   ROS_LOG_DIR=os.path.join(home, "log"), PYTHONUNBUFFERED="1")
        return env

    def start(self, pc, key, argv):
        # On the PC's own "disk": its processes' output beside its ROS logs.
        os.makedirs(os.path.join(self.directory, pc), exist_ok=True)
        log = open(os.path.join(self.directory, pc, "%s.log" % key), "a")
        self.logs[key] = log.name
        log.write("\n==== %s: %s\n" % (time.strftime("%H:%M:%S"), " ".join(argv)))
        log.flush()
        self.processes[key] = subprocess.Popen(
            ["ip", "netns", "exec", self.ns[pc]] + argv, env=self.env(pc), stdout=log,
            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
        log.close()
        return self.processes[key]

    def on(self, pc, argv, timeout=60, check=True):
        return run(["ip", "netns", "exec", self.ns[pc]] + argv, timeout=timeout, check=check,
                   env=self.env(pc))

    def pids(self, pc):
        out = run(["ip", "netns", "pids", self.ns[pc]], check=False)
        return [int(p) for p in out.stdout.split() if p.isdigit()]

    def kill(self, pc, match=None):
        """SIGKILL every process of the PC's namespace (a power cut), or those whose command
        line contains one of `match`. Returns how many."""
        killed = 0
        for _ in range(20):
            victims = []
            for pid in self.pids(pc):
                if match is not None:
                    try:
                        with open("/proc/%d/cmdline" % pid, "rb") as f:
                            cmdline = f.read().replace(b"\0", b" ").decode(errors="replace")
                    except OSError:
                        continue
                    if not any(m in cmdline for m in match):
                        continue
                victims.append(pid)
            if not victims:
                break
            for pid in victims:
                try:
                    os.kill(pid, signal.SIGKILL)
                    killed += 1
                except ProcessLookupError:
                    pass
            time.sleep(0.2)
        for p in self.processes.values():
            try:
                p.wait(timeout=0.1)
            except subprocess.TimeoutExpired:
                pass
        return killed

    def start_roscore(self):
        self.start("master", "roscore", ["roscore", "-p", "11311"])
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            out = self.on("master", ["rosparam", "get", "/run_id"], check=False, timeout=20)
            if out.returncode == 0 and out.stdout.strip():
                return out.stdout.strip()
            time.sleep(0.5)
        raise RuntimeError("roscore did not come up: see %s" % self.logs["roscore"])

    def boot_stand(self, pc, archive_url):
        """The stand PC's service manager: its launch, started again whenever it ends."""
        device, config, seed = DEVICES[pc]
        launch = ("roslaunch --wait accel_intrinsics lab_stand.launch stand:={pc} steps:={steps} "
                  "time_scale:={scale} wall_epoch_s:={epoch:.3f} seed:={seed} "
                  "device_config:={config} output_dir:={out} archive:={archive} "
                  "archive_device:={device}").format(
            pc=pc, steps=STEPS, scale=TIME_SCALE, epoch=self.wall_epoch_s, seed=seed,
            config=os.path.join(REPO, "config", config),
            out=os.path.join(self.directory, pc, "disk"), archive=archive_url, device=device)
        loop = ("while true; do %s; echo \"[%s] roslaunch ended (status $?); starting it again\"; "
                "sleep 1; done") % (launch, pc)
        self.start(pc, pc, ["bash", "-c", loop])

    def start_postgres(self):
        """PostgreSQL on the archive server, listening on the lab network. Returns its URL, or
        None with the reason in self.postgres_reason."""
        def binary(name):
            found = shutil.which(name)
            if found:
                return found
            import glob
            candidates = sorted(glob.glob("/usr/lib/postgresql/*/bin/" + name))
            return candidates[-1] if candidates else None
        initdb, pg_ctl = binary("initdb"), binary("pg_ctl")
        if not initdb or not pg_ctl:
            self.postgres_reason = "no PostgreSQL server installed"
            return None
        try:
            entry = pwd.getpwnam("postgres")
        except KeyError:
            self.postgres_reason = "no `postgres` user to run the server as"
            return None
        directory = tempfile.mkdtemp(prefix="accel_lab_pg_")
        os.chown(directory, entry.pw_uid, entry.pw_gid)
        self.postgres = (pg_ctl, os.path.join(directory, "data"), directory)
        as_postgres = ["runuser", "-u", "postgres", "--"]
        out = self.on("archive", as_postgres + [initdb, "-D", self.postgres[1], "-A", "trust",
                                                "-U", "postgres", "--no-sync"],
                      check=False, timeout=120)
        if out.returncode != 0:
            self.postgres_reason = "initdb failed: %s" % out.stdout.strip()[-300:]
            return None
        with open(os.path.join(self.postgres[1], "pg_hba.conf"), "a") as f:
            f.write("host all all %s.0/24 trust\n" % SUBNET)
        options = ("-p 5432 -k %s -c listen_addresses=%s -c fsync=off" % (directory,
                                                                          ADDRESS["archive"]))
        out = self.on("archive", as_postgres + [pg_ctl, "-D", self.postgres[1], "-o", options,
                                                "-l", os.path.join(directory, "server.log"),
                                                "-w", "-t", "60", "start"],
                      check=False, timeout=120)
        if out.returncode != 0:
            self.postgres_reason = "the server did not start: %s" % out.stdout.strip()[-300:]
            return None
        # Across the lab network, from the master PC.
        self.on("master", ["psql", "-h", ADDRESS["archive"], "-U", "postgres", "-d", "postgres",
                           "-c", "CREATE DATABASE lab"])
        return "postgresql://postgres@%s:5432/lab" % ADDRESS["archive"]

    def close(self):
        for pc in ("master", "stand1", "stand2", "archive"):
            if self.ns[pc] in self.created:
                self.kill(pc)
        if self.postgres:
            shutil.rmtree(self.postgres[2], ignore_errors=True)
        for name in reversed(self.created):
            run(["ip", "netns", "del", name], check=False)
        self.created = []

    def leftovers(self):
        names = run(["ip", "netns", "list"], check=False).stdout
        links = run(["ip", "-o", "link"], check=False).stdout
        return [n for n in self.ns.values() if n in names] + \
            [l.split(":")[1].strip() for l in links.splitlines() if self.tag in l]


def read(path):
    try:
        with open(path, errors="replace") as f:
            return f.read()
    except OSError:
        return ""


def grep_tree(directory, pattern):
    """Lines matching `pattern` in every file under `directory` (the ROS logs of a PC)."""
    found = []
    for root, _, files in os.walk(directory):
        for name in files:
            for line in read(os.path.join(root, name)).splitlines():
                if re.search(pattern, line):
                    found.append(line.strip())
    return found


def wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.5)
    raise AssertionError("timed out after %.0f s waiting for %s" % (timeout, what))


def test_two_stands_on_a_namespace_lab_survive_a_cut_link_a_rebooted_stand_and_a_master_restart(
        tmp_path):
    reason = stand_built()
    if reason:
        pytest.skip(reason)
    lab = Lab(str(tmp_path))
    def interrupted(signum, frame):
        raise KeyboardInterrupt("SIGTERM")  # the `finally` below still removes the lab
    previous_sigterm = signal.signal(signal.SIGTERM, interrupted)
    try:
        reason = lab.create()
        if reason:
            pytest.skip(reason)
        archive_url = lab.start_postgres()
        if archive_url is None:
            # The archive then lives on the master PC (the stands share this machine's disk).
            archive_url = "sqlite:///" + str(tmp_path / "master" / "archive.db")
            print("no PostgreSQL on the archive server (%s): SQLite on the master" %
                  lab.postgres_reason)
        first_run_id = lab.start_roscore()
        for pc in ("stand1", "stand2"):
            lab.boot_stand(pc, archive_url)

        def services_up():
            out = lab.on("master", ["rosservice", "list"], check=False, timeout=30)
            return all("/%s/%s" % (pc, s) in out.stdout for pc in ("stand1", "stand2")
                       for s in ("calibration/get_intrinsics", "gimbal_controller/start"))
        wait_for(services_up, 90, "both stands' services at the master")

        report = str(tmp_path / "master" / "supervise.json")
        supervise = lab.start("master", "supervise", [
            "/usr/bin/python3", os.path.join(REPO, "scripts", "supervise"), "stand1", "stand2",
            "--json", report, "--timeout", "400", "--silence-s", "4", "--max-sigma", "5",
            "--quiet"])
        t0 = time.monotonic()

        def sleep_until(s):
            time.sleep(max(0.0, t0 + s - time.monotonic()))
            assert supervise.poll() is None, "supervise ended before the faults:\n%s" % read(
                lab.logs["supervise"])[-4000:]

        # 1. stand1's cable pulled for 8 s.
        sleep_until(10)
        lab.cable("stand1", False)
        sleep_until(18)
        lab.cable("stand1", True)
        # 2. stand2's PC loses power, boots again 3 s later.
        sleep_until(26)
        assert lab.kill("stand2") > 0
        sleep_until(29)
        lab.boot_stand("stand2", archive_url)
        # 3. the master restarts (the supervisor on the same PC keeps running).
        sleep_until(48)
        assert lab.kill("master", match=("roscore", "rosmaster", "rosout")) > 0
        sleep_until(51)
        second_run_id = lab.start_roscore()
        assert second_run_id != first_run_id

        try:
            status = supervise.wait(timeout=420)
        except subprocess.TimeoutExpired:
            status = None
        log = read(lab.logs["supervise"])
        assert status == 0, "supervise exit status %s:\n%s" % (status, log[-6000:])
        with open(report) as f:
            result = json.load(f)

        # Nothing lost: complete tables, fits of the simulated truth.
        for pc in ("stand1", "stand2"):
            entry = result["rigs"][pc]
            assert entry["success"], entry
            assert entry["result"]["positions"] == {"x": STEPS, "y": STEPS, "z": STEPS}, entry
            assert entry["max_abs_z"] < 5.0, entry
        # Every fault named by the supervisor...
        faults1 = " | ".join(result["rigs"]["stand1"]["faults"])
        faults2 = " | ".join(result["rigs"]["stand2"]["faults"])
        master = " | ".join(result["master_faults"])
        assert "no word from the rig" in faults1 and "heard again" in faults1, faults1
        assert ("the gimbal controller restarted" in faults2 or
                "calibration node restarted" in faults2), faults2
        assert "restarted (run_id %s -> %s)" % (first_run_id, second_run_id) in master, master
        for pc in ("stand1", "stand2"):
            home = os.path.join(str(tmp_path), pc)
            # ... and by the stands: master_watch ended each launch, the run went on from the
            # checkpoint.
            assert grep_tree(home, r"master_watch: the ROS master restarted"), pc
            assert grep_tree(home, r"from its checkpoint|resuming after"), pc
        assert grep_tree(os.path.join(str(tmp_path), "stand2"),
                         r"stand restarted .*from its checkpoint"), \
            "stand2 did not continue its run from the checkpoint after its reboot"
        # Both results in the archive, one record per device, each with its rig.
        listing = lab.on("master", ["/usr/bin/python3", os.path.join(REPO, "scripts", "archive"),
                                    "--archive", archive_url, "list"]).stdout
        for pc, (device, _, _) in DEVICES.items():
            assert re.search(r"^%s\s+%s\s+[1-9]" % (device, pc), listing, re.M), listing
    finally:
        try:
            lab.close()
        finally:
            signal.signal(signal.SIGTERM, previous_sigterm)
    assert not lab.leftovers(), "left behind: %s" % lab.leftovers()
