#!/usr/bin/env python3
"""The dashboard in a real browser (test/ros/dashboard.test, docs/dashboard.md): two simulated
stands and the dashboard on one master, the page opened by headless Chromium through Selenium.

Checks: both cards appear; each dwell the calibration node publishes shows as a point of the
stand's plot within ~push_latency_s, and the plot grows dwell by dwell; when rig1 is done its
plot holds as many points as its position_table.csv has rows, and its result table equals its
result file (intrinsics.yaml, the keys of offline_fit's JSON) to the digits printed; rig2, killed
(SIGKILL) mid-run, shows as lost, not before the dashboard's lost_after_s of silence (counted
from the last message of rig2 this test heard, less ~heard_tolerance_s) and within lost_after_s
+ its discovery period + ~lost_slack_s of the kill; its device serial, a piece of HTML, shows as
text; the browser's console holds no error. rig1's serial, also HTML, shows as text in the lab
archive's view once its calibration node archived the result, and so does each rig's control
chart (six canvases with points) of /dashboard/check_standards. The page at the end is saved as
a PNG (~screenshot).
"""

import csv
import decimal
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
import unittest
import urllib.request
import xmlrpc.client

import rosgraph
import rospy
import rostest
import yaml
from std_srvs.srv import Trigger

from diagnostic_msgs.msg import DiagnosticStatus

from accel_intrinsics.msg import Dwell

from selenium import webdriver
from selenium.common.exceptions import NoAlertPresentException
from selenium.webdriver.chrome.service import Service

PKG = "accel_intrinsics"
# Chromium as root in a container: no sandbox, nothing fetched from the network.
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--window-size=1600,1500"]


def start_browser(profile):
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in CHROMIUM_FLAGS + ["--user-data-dir=" + profile]:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


def node_pid(name):
    uri = rosgraph.Master("/dashboard_browser").lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/dashboard_browser")
    assert code == 1, "getPid of %s failed" % name
    return pid


def printed_matches(text, value):
    """The printed number equals `value` to the digits printed (half a unit of the last)."""
    d = decimal.Decimal(text)
    half = decimal.Decimal(5) * decimal.Decimal(10) ** (d.as_tuple().exponent - 1)
    return abs(d - decimal.Decimal(repr(float(value)))) <= half * decimal.Decimal("1.000001")


class DashboardInBrowser(unittest.TestCase):
    def setUp(self):
        self.url = rospy.get_param("~url", "http://127.0.0.1:8765/")
        self.done_ns = rospy.get_param("~done_ns", "rig1")
        self.kill_ns = rospy.get_param("~kill_ns", "rig2")
        self.output_dir = rospy.get_param("~output_dir")
        self.kill_serial = rospy.get_param("/%s/calibration/archive_device" % self.kill_ns)
        # rig1's serial, also HTML, reaches the page through the lab archive (after its result).
        self.done_serial = rospy.get_param("/%s/calibration/archive_device" % self.done_ns, "")
        self.timeout_s = rospy.get_param("~timeout_s", 120.0)
        # Wall seconds from a dwell's arrival here to its point on the page (rospy, the
        # dashboard, its WebSocket, Chromium): wide enough for a loaded 2-core machine, narrow
        # enough that a page updated only every few dwells fails (rig1: a dwell every ~0.7 s).
        self.push_latency_s = rospy.get_param("~push_latency_s", 3.0)
        # Lost: after the dashboard's ~lost_after_s of silence, checked once per discovery pass
        # (~discovery_period_s, the node's default 1.0 unless set), then pushed to the page.
        self.lost_after_s = rospy.get_param("/dashboard/lost_after_s", 3.0)
        self.discovery_period_s = rospy.get_param("/dashboard/discovery_period_s", 1.0)
        self.lost_slack_s = rospy.get_param("~lost_slack_s", 3.0)
        # This test and the dashboard hear rig2's last message at slightly different moments.
        self.heard_tolerance_s = rospy.get_param("~heard_tolerance_s", 0.3)
        self.screenshot = rospy.get_param("~screenshot", "")
        self.lock = threading.Lock()
        self.arrivals = {self.done_ns: [], self.kill_ns: []}  # (wall time, index)
        self.subs = [rospy.Subscriber("/%s/calibration/dwell" % ns, Dwell, self.on_dwell, ns,
                                      queue_size=100) for ns in self.arrivals]
        # The last time this test heard rig2 (topics the dashboard hears it by too).
        self.kill_heard = None
        self.subs += [rospy.Subscriber("/%s/%s" % (self.kill_ns, topic), DiagnosticStatus,
                                       self.on_kill_ns_message, queue_size=10)
                      for topic in ("calibration/status", "gimbal_controller/progress")]
        self.profile = tempfile.mkdtemp(prefix="dashboard_chromium_")
        self.browser = start_browser(self.profile)

    def tearDown(self):
        self.browser.quit()
        shutil.rmtree(self.profile, ignore_errors=True)
        archive = rospy.get_param("/dashboard/archive", "")  # a new SQLite file per run
        if archive.startswith("sqlite:///") and os.path.exists(archive[len("sqlite:///"):]):
            os.remove(archive[len("sqlite:///"):])

    def on_dwell(self, msg, ns):
        with self.lock:
            self.arrivals[ns].append((time.monotonic(), msg.index))
            if ns == self.kill_ns:
                self.kill_heard = time.monotonic()

    def on_kill_ns_message(self, msg):
        with self.lock:
            self.kill_heard = time.monotonic()

    def js(self, script, *args):
        return self.browser.execute_script(script, *args)

    def card_info(self, ns):
        return self.js("""
            const c = document.querySelector('section.card[data-ns="' + arguments[0] + '"]');
            if (!c) return null;
            const p = c.querySelector('.points');
            return {count: p && p.dataset.count ? Number(p.dataset.count) : 0,
                    state: c.querySelector('.state').textContent,
                    lost: c.classList.contains('lost'),
                    device: c.querySelector('.device').textContent};""", "/" + ns)

    def wait_for(self, what, predicate, timeout_s):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            value = predicate()
            if value:
                return value
            time.sleep(0.05)
        self.fail("timed out after %.0f s waiting for %s" % (timeout_s, what))

    def page_served(self):
        try:
            with urllib.request.urlopen(self.url, timeout=2.0) as r:
                return r.status == 200
        except OSError:
            return False

    def test_two_stands_live_in_the_browser(self):
        self.wait_for("the dashboard at " + self.url, self.page_served, 30.0)
        self.browser.get(self.url)
        self.wait_for("both cards", lambda: self.card_info(self.done_ns) and
                      self.card_info(self.kill_ns), 30.0)
        for ns in (self.done_ns, self.kill_ns):
            start = rospy.ServiceProxy("/%s/gimbal_controller/start" % ns, Trigger)
            start.wait_for_service(10.0)
            self.assertTrue(start().success)

        # Live: every dwell rig1's node publishes is a point of its plot within push_latency_s.
        seen_counts = set()
        late = []
        first_shown = {}  # point index -> the first time (after a read) the page showed it
        end = time.monotonic() + self.timeout_s
        while time.monotonic() < end:
            # The page is read after `asked`: a dwell heard push_latency_s before it is due.
            asked = time.monotonic()
            info = self.card_info(self.done_ns)
            read = time.monotonic()
            for i in range(info["count"]):
                first_shown.setdefault(i, read)
            seen_counts.add(info["count"])
            with self.lock:
                due = [i for t, i in self.arrivals[self.done_ns]
                       if asked - t > self.push_latency_s]
            if due and info["count"] < max(due) + 1:
                late.append((max(due) + 1, info["count"]))
            if info["state"] == "RESULT" and self.js(
                    "return !!document.querySelector('section.card[data-ns=\"/%s\"] table.result')"
                    % self.done_ns):
                break
            time.sleep(0.05)
        else:
            self.fail("rig %s shows no result after %.0f s" % (self.done_ns, self.timeout_s))
        self.assertEqual(late, [], "points later than %.1f s (expected, shown)"
                         % self.push_latency_s)
        self.assertGreaterEqual(len(seen_counts), 4, "the plot did not grow dwell by dwell: %s"
                                % sorted(seen_counts))
        with self.lock:  # the figure for the log: the slowest dwell, heard here to shown
            slowest = max((first_shown[i] - t for t, i in self.arrivals[self.done_ns]
                           if i in first_shown), default=float("nan"))

        # Done: points = rows of the position table = dwell messages.
        # The node's files of its newest run (output_dir/<device>/latest/, docs/results.md).
        run_dir = os.path.join(self.output_dir, self.done_ns, "unnamed", "latest")
        with open(os.path.join(run_dir, "position_table.csv")) as f:
            rows = [r for r in csv.reader(l for l in f if not l.startswith("#"))][1:]
        info = self.card_info(self.done_ns)
        self.assertEqual(info["count"], len(rows))
        with self.lock:
            self.assertEqual(len(self.arrivals[self.done_ns]), len(rows))
        drawn = self.js("return [...document.querySelectorAll('section.card[data-ns=\"/%s\"] "
                        "canvas.means')].map(c => Number(c.dataset.points))" % self.done_ns)
        self.assertEqual(drawn, [len(rows)] * 3)

        # The result table against the node's result file, to the printed digits.
        with open(os.path.join(run_dir, "intrinsics.yaml")) as f:
            doc = yaml.safe_load(f)
        cells = self.js("return [...document.querySelectorAll('section.card[data-ns=\"/%s\"] "
                        "td[data-key]')].map(td => [td.dataset.key, td.textContent])"
                        % self.done_ns)
        self.assertGreaterEqual(len(cells), 23)
        for key, text in cells:
            value = doc
            for part in key.split("."):
                value = value[part]
            self.assertTrue(printed_matches(text, value),
                            "%s: shown %s, file %r" % (key, text, value))

        # rig2 is killed mid-run (SIGKILL: nothing unregisters): lost after lost_after_s of
        # silence, not before, and within lost_after_s + a discovery pass + lost_slack_s.
        info = self.card_info(self.kill_ns)
        self.assertFalse(info["lost"])
        self.assertNotIn(info["state"], ("RESULT", "FAILED", "ABORTED"), "rig2 finished too soon")
        with self.lock:
            self.assertIsNotNone(self.kill_heard, "this test heard nothing of rig2")
        for node in ("gimbal_controller", "accelerometer", "calibration"):
            os.kill(node_pid("/%s/%s" % (self.kill_ns, node)), signal.SIGKILL)
        killed = time.monotonic()
        lost_within_s = self.lost_after_s + self.discovery_period_s + self.lost_slack_s
        self.wait_for("rig2 lost", lambda: self.card_info(self.kill_ns)["lost"],
                      lost_within_s + 2.0)
        shown = time.monotonic()  # the page showed it lost at or before this
        lost_after = shown - killed
        with self.lock:
            silent = shown - self.kill_heard
        self.assertLess(lost_after, lost_within_s, "rig2 shown lost %.2f s after the kill"
                        % lost_after)
        self.assertGreaterEqual(silent, self.lost_after_s - self.heard_tolerance_s,
                                "rig2 shown lost after %.2f s of silence (lost_after_s %.1f)"
                                % (silent, self.lost_after_s))
        self.assertFalse(self.card_info(self.done_ns)["lost"])

        # A serial that is a piece of HTML is text: no element made of it, no alert.
        self.assertEqual(self.card_info(self.kill_ns)["device"], "device " + self.kill_serial)
        self.assertEqual(self.js("return document.querySelectorAll('main img').length"), 0)
        with self.assertRaises(NoAlertPresentException):
            self.browser.switch_to.alert.text

        if self.done_serial:
            serials = self.wait_for("rig1's record in the archive view", lambda: self.js(
                "return [...document.querySelectorAll('#archive h3.serial')]"
                ".map(h => h.textContent)"), 30.0)
            self.assertEqual(serials, [self.done_serial])
            self.assertEqual(self.js("return document.querySelectorAll('img').length"), 0)

        # ~check_standards: each rig's control chart, its serial shown as text.
        standards = rospy.get_param("/dashboard/check_standards", {})
        self.assertTrue(standards, "dashboard.test sets the dashboard's check_standards")
        for rig, serial in sorted(standards.items()):
            chart = self.wait_for("the control chart of rig " + rig, lambda: self.js("""
                const c = [...document.querySelectorAll('#archive .control-chart')]
                    .find(e => e.dataset.rig === arguments[0]);
                if (!c) return null;
                const canvases = [...c.querySelectorAll('canvas.chart')];
                if (!canvases.length || canvases.some(k => Number(k.dataset.points) < 1)) return null;
                return {title: c.querySelector('h3').textContent,
                        line: c.querySelector('.line').textContent,
                        canvases: canvases.length};""", rig), 30.0)
            self.assertEqual(chart["title"], "control chart of rig " + rig)
            self.assertTrue(chart["line"].startswith("check standard " + serial + " "))
            self.assertEqual(chart["canvases"], 6)
            self.assertEqual(self.js("return document.querySelectorAll('img').length"), 0)

        if self.screenshot:
            os.makedirs(os.path.dirname(self.screenshot), exist_ok=True)
            self.browser.save_screenshot(self.screenshot)
        errors = [e for e in self.browser.get_log("browser") if e["level"] == "SEVERE"]
        self.assertEqual(errors, [])
        rospy.loginfo("dashboard_browser: %d points (the slowest shown %.2f s after it was "
                      "heard), rig2 lost %.2f s after the kill (%.2f s after its last message), "
                      "%d result cells", len(rows), slowest, lost_after, silent, len(cells))


if __name__ == "__main__":
    rospy.init_node("dashboard_browser")
    rostest.rosrun(PKG, "dashboard_browser", DashboardInBrowser, sys.argv)
