"""supervise waits for its subscriptions' publishers before it acts (the mount check's first
resume, a run's start): a subscription counts as connected once a publisher answered the TCPROS
handshake, not when rospy first counts the connection (it does so before the handshake, which a
thread then makes). The subscribers are written here as rospy lays them out (get_num_connections,
impl.connections, each connection's header: None until the publisher's header was read); no ROS
master is needed. On a stand: test/ros/mount_check.test (ImuTopicWithoutPublisherIsNamed)."""
import threading
import time

import pytest


class Connection:
    def __init__(self, header=None):
        self.header = header


class Impl:
    def __init__(self):
        self.connections = []


class Subscriber:
    def __init__(self, name):
        self.resolved_name = name
        self.impl = Impl()

    def get_num_connections(self):
        return len(self.impl.connections)


def test_no_publisher_is_missing_after_the_timeout(supervise):
    sub = Subscriber("/imu")
    t0 = time.monotonic()
    assert supervise.wait_connected([sub], timeout_s=0.3) == ["/imu"]
    assert time.monotonic() - t0 >= 0.3


def test_a_connection_before_its_handshake_is_not_connected(supervise):
    sub = Subscriber("/gimbal/command")
    sub.impl.connections.append(Connection(header=None))
    assert not supervise.connected(sub)
    assert supervise.wait_connected([sub], timeout_s=0.2) == ["/gimbal/command"]
    sub.impl.connections[0].header = {"type": "accel_intrinsics/GimbalCommand"}
    assert supervise.connected(sub)


def test_waits_until_every_subscriber_is_connected(supervise):
    imu, command = Subscriber("/imu"), Subscriber("/gimbal/command")
    command.impl.connections.append(Connection(header={"type": "t"}))
    imu.impl.connections.append(Connection(header=None))

    def handshake():
        time.sleep(0.3)
        imu.impl.connections[0].header = {"type": "sensor_msgs/Imu"}

    thread = threading.Thread(target=handshake)
    t0 = time.monotonic()
    thread.start()
    missing = supervise.wait_connected([imu, command], timeout_s=5.0)
    waited = time.monotonic() - t0
    thread.join()
    assert missing == []
    assert 0.3 <= waited < 2.0  # it waited for the handshake, and no longer than needed


def test_one_of_several_publishers_connected_is_enough(supervise):
    sub = Subscriber("/imu")
    sub.impl.connections += [Connection(header=None), Connection(header={"type": "t"})]
    assert supervise.wait_connected([sub], timeout_s=0.1) == []
