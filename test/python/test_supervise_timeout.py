"""supervise's timeout (docs/design.md section 15, "Launch for hardware"): it follows the protocol's
expected duration (the gimbal controller's time_left_s when the run starts) and does not count
the time the controller waits for the operator (REMOUNT, WAIT_OPERATOR), in the run's own time
(progress stamps) and, with --timeout, in wall seconds. The progress messages are written here;
no ROS master is needed (the Rig is built without subscribing)."""

import pytest


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def make_rig(supervise, monkeypatch):
    clock = Clock()
    monkeypatch.setattr(supervise.time, "monotonic", clock)
    rig = supervise.Rig.__new__(supervise.Rig)
    rig.label = "/"
    rig.progress = {}
    rig.seen_running = False
    rig.first_stamp = rig.last_stamp = rig.expected_s = rig.last_progress_wall = None
    rig.operator_ros_s = rig.operator_wall_s = 0.0
    return rig, clock


def feed(rig, clock, state, stamp, time_left=None, wall_step=1.0):
    """One progress message at ROS time `stamp`, `wall_step` wall seconds after the last."""
    clock.t += wall_step
    progress = {"state": state, "stamp": "%.3f" % stamp}
    if time_left is not None:
        progress["time_left_s"] = "%.1f" % time_left
    if state in ("STARTING", "MOVING", "SETTLED", "REMOUNT", "WAIT_OPERATOR"):
        rig.seen_running = True
    rig._clock(progress)
    rig.progress = progress


@pytest.mark.parametrize("operator_state", ["REMOUNT", "WAIT_OPERATOR"])
def test_operator_time_is_not_run_time(supervise, monkeypatch, operator_state):
    rig, clock = make_rig(supervise, monkeypatch)
    t0 = clock.t
    feed(rig, clock, "MOVING", 0.0, time_left=100.0)  # the protocol expects 100 s: limit 270 s
    feed(rig, clock, "SETTLED", 50.0)
    for stamp in range(60, 1060, 10):  # 1000 s waiting for a person
        feed(rig, clock, operator_state, float(stamp))
    feed(rig, clock, "MOVING", 1070.0)
    assert rig.expected_s == 100.0
    assert rig.operator_ros_s == pytest.approx(1010.0)  # 60 .. 1070: the wait, to the next move
    assert rig.timed_out(clock.t, t0, None) is None
    # 270 s of the run's own time is the limit: 1070 - 1010 = 60 s so far
    feed(rig, clock, "SETTLED", 1270.0)
    assert rig.timed_out(clock.t, t0, None) is None
    feed(rig, clock, "SETTLED", 1300.0)
    reason = rig.timed_out(clock.t, t0, None)
    assert reason is not None and "expects 100 s" in reason


def test_wall_timeout_excludes_the_operator_too(supervise, monkeypatch):
    rig, clock = make_rig(supervise, monkeypatch)
    t0 = clock.t
    feed(rig, clock, "MOVING", 0.0, time_left=100.0, wall_step=5.0)
    feed(rig, clock, "REMOUNT", 5.0, wall_step=5.0)
    feed(rig, clock, "REMOUNT", 500.0, wall_step=500.0)  # the person takes 500 s
    assert rig.timed_out(clock.t, t0, 60.0) is None     # 10 s of run, 500 s of waiting
    feed(rig, clock, "MOVING", 510.0, wall_step=10.0)
    assert rig.operator_wall_s == pytest.approx(510.0)
    assert rig.timed_out(clock.t, t0, 60.0) is None
    clock.t += 60.0
    assert "timed out after 60 s" in rig.timed_out(clock.t, t0, 60.0)


def test_a_protocol_that_never_runs_fails_after_the_fallback(supervise, monkeypatch):
    rig, clock = make_rig(supervise, monkeypatch)
    t0 = clock.t
    feed(rig, clock, "IDLE", 0.0)
    assert rig.timed_out(clock.t, t0, None) is None
    clock.t += supervise.NO_PROGRESS_LIMIT_S + 1.0
    assert "no running protocol" in rig.timed_out(clock.t, t0, None)
