// The ros_joint driver without ROS (docs/design.md section 15): a joint controller written here
// (each joint a damped second-order motion toward its Float64 command, with overshoot, reporting
// JointState at 50 Hz) drives it through the protocol; a silent joint and a joint that never
// arrives are faults that name the joint.
#include "accel_intrinsics/drivers/ros_joint_gimbal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/run/gimbal_protocol.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// The test's joint controller: x'' = wn^2 (command - x) - 2 zeta wn x' (zeta 0.4: ~25 %
// overshoot), integrated in 1 ms steps; JointState every 20 ms (50 Hz).
class JointController : public ai::GimbalLinks {
 public:
  struct Joint {
    std::string name, topic;
    double x = 0.0, v = 0.0, command = 0.0;
    bool silent = false, stuck = false;
  };
  std::vector<Joint> joints;
  std::map<std::string, std::vector<double>> commands;  // per topic, rad
  double wn = 12.0, zeta = 0.4;

  void publish_command(const std::string& topic, double position_rad) override {
    commands[topic].push_back(position_rad);
    for (Joint& j : joints)
      if (j.topic == topic) j.command = position_rad;
  }
  void step(double dt) {
    for (Joint& j : joints) {
      if (j.stuck) continue;
      const double a = wn * wn * (j.command - j.x) - 2.0 * zeta * wn * j.v;
      j.v += a * dt;
      j.x += j.v * dt;
    }
  }
  void report(double t_s, ai::GimbalDriver* driver) const {
    std::vector<std::string> names;
    std::vector<double> positions;
    names.push_back("unmapped_wheel");  // other joints in the same message are ignored
    positions.push_back(123.0);
    for (const Joint& j : joints) {
      if (j.silent) continue;
      names.push_back(j.name);
      positions.push_back(j.x);
    }
    driver->on_joint_state(t_s, names, positions);
  }
};

ai::RosJointOptions options() {
  ai::RosJointOptions o;
  o.axes["X"] = {"outer_joint", "outer_controller/command"};
  o.axes["Y"] = {"inner_joint", "inner_controller/command"};
  o.tolerance_deg = 0.05;
  o.settle_s = 0.3;
  o.move_timeout_s = 5.0;
  // The axis map of config/grbl_gimbal.yaml, with a sign and a zero on phase z.
  o.axis_map.phases[0].axis = "X";
  o.axis_map.phases[0].hold = {{"Y", 0.0}};
  o.axis_map.phases[1].axis = "X";
  o.axis_map.phases[1].hold = {{"Y", 90.0}};
  o.axis_map.phases[2].axis = "Y";
  o.axis_map.phases[2].sign = -1.0;
  o.axis_map.phases[2].zero_deg = 10.0;
  o.axis_map.phases[2].hold = {{"X", 90.0}};
  return o;
}

JointController controller() {
  JointController c;
  c.joints.push_back({"outer_joint", "outer_controller/command"});
  c.joints.push_back({"inner_joint", "inner_controller/command"});
  return c;
}

// Runs the driver and the controller from t0 to t1 on a 1 ms clock; JointState every 20 ms,
// update() every 10 ms (the controller's tick). Returns the first time settled, or -1.
double run(ai::RosJointGimbal* driver, JointController* c, double t0, double t1) {
  double settled_at = -1.0;
  for (int k = 0; t0 + k * 1e-3 <= t1; ++k) {
    const double t = t0 + k * 1e-3;
    c->step(1e-3);
    if (k % 20 == 0) c->report(t, driver);
    if (k % 10 == 0) {
      driver->update(t);
      if (settled_at < 0.0 && driver->settled(t)) settled_at = t;
    }
  }
  return settled_at;
}

ai::GimbalTarget target(core::Phase p, double alpha_deg) {
  ai::GimbalTarget t;
  t.phase = p;
  t.angle_rad = alpha_deg * kDeg;
  t.steps = 4;
  return t;
}

}  // namespace

TEST(RosJointGimbal, CommandsTheAxisMapAndSettlesAfterTheOvershoot) {
  JointController c = controller();
  ai::RosJointGimbal driver(options());
  driver.connect(&c);
  const ai::GimbalDriverTopics topics = driver.topics();
  EXPECT_EQ(topics.joint_states, "joint_states");
  ASSERT_EQ(topics.command_topics.size(), 2u);

  run(&driver, &c, 0.0, 0.5);
  driver.move_to(target(core::Phase::Z, 30.0), 0.5);
  // Phase z: Y = 10 - 30 = -20 deg, X held at 90 deg (rad on the wire).
  EXPECT_NEAR(c.commands["inner_controller/command"].back(), -20.0 * kDeg, 1e-12);
  EXPECT_NEAR(c.commands["outer_controller/command"].back(), 90.0 * kDeg, 1e-12);
  EXPECT_FALSE(driver.settled(0.5));

  // The joints overshoot: the first pass through the tolerance band does not settle.
  double first_within = -1.0;
  double settled = -1.0;
  for (int k = 1; k <= 4000 && settled < 0.0; ++k) {
    const double t = 0.5 + k * 1e-3;
    c.step(1e-3);
    if (k % 20 == 0) c.report(t, &driver);
    if (k % 10 == 0) {
      driver.update(t);
      if (first_within < 0.0 && std::abs(c.joints[0].x - 90.0 * kDeg) < 0.05 * kDeg)
        first_within = t;
      if (driver.settled(t)) settled = t;
    }
  }
  ASSERT_GT(settled, 0.0) << "never settled";
  EXPECT_GT(first_within, 0.0);
  EXPECT_GT(settled, first_within + 0.3) << "settled before settle_s inside the tolerance";
  for (const auto& j : c.joints) EXPECT_NEAR(j.x, j.command, 0.05 * kDeg);
  // The reported joints through the axis map and the stage kinematics: phase z at 30 deg.
  const Eigen::Vector3d f =
      driver.orientation(settled).world_dut().transpose() * Eigen::Vector3d(0, 0, 1);
  EXPECT_NEAR((f - Eigen::Vector3d(std::sin(30 * kDeg), std::cos(30 * kDeg), 0.0)).norm(), 0.0,
              2e-3);
}

TEST(RosJointGimbal, SilentJointIsAFaultNamingIt) {
  JointController c = controller();
  c.joints[1].silent = true;
  ai::RosJointGimbal driver(options());
  driver.connect(&c);
  run(&driver, &c, 0.0, 1.9);  // within 2 s: no fault yet
  try {
    run(&driver, &c, 1.9, 2.5);
    FAIL() << "no fault for a silent joint";
  } catch (const ai::GimbalFault& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("inner_joint"), std::string::npos) << what;
    EXPECT_EQ(what.find("outer_joint"), std::string::npos) << what;
    EXPECT_NE(what.find("no JointState"), std::string::npos) << what;
  }
}

TEST(RosJointGimbal, JointThatNeverArrivesIsAFaultNamingIt) {
  JointController c = controller();
  c.joints[0].stuck = true;  // outer joint: brake on
  ai::RosJointGimbal driver(options());
  driver.connect(&c);
  run(&driver, &c, 0.0, 0.2);
  driver.move_to(target(core::Phase::X, 60.0), 0.2);
  EXPECT_LT(run(&driver, &c, 0.2, 5.1), 0.0);  // move_timeout_s = 5: not yet
  try {
    run(&driver, &c, 5.1, 5.5);
    FAIL() << "no fault for a joint that never arrives";
  } catch (const ai::GimbalFault& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("outer_joint"), std::string::npos) << what;
    EXPECT_NE(what.find("60.000"), std::string::npos) << what;  // its target
    EXPECT_EQ(what.find("inner_joint"), std::string::npos) << what;
  }
}

// The fault a user reads names the limits as they were set (a half-second timeout is not
// rounded to a whole one), so the message says which parameter to raise and from what.
TEST(RosJointGimbal, MoveTimeoutFaultQuotesTheLimitsAsSet) {
  JointController c = controller();
  c.joints[0].stuck = true;
  ai::RosJointOptions o = options();
  o.move_timeout_s = 2.5;
  ai::RosJointGimbal driver(o);
  driver.connect(&c);
  run(&driver, &c, 0.0, 0.2);
  driver.move_to(target(core::Phase::X, 60.0), 0.2);
  try {
    run(&driver, &c, 0.2, 3.0);
    FAIL() << "no fault for a joint that never arrives within 2.5 s";
  } catch (const ai::GimbalFault& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("within move_timeout_s = 2.5 s"), std::string::npos) << what;
    EXPECT_NE(what.find("(tolerance_deg = 0.050)"), std::string::npos) << what;
  }
}

TEST(RosJointGimbal, RejectsAnAxisMapOnUnknownAxes) {
  ai::RosJointOptions o = options();
  o.axis_map.phases[2].axis = "Z";
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = options();
  o.axes["Y"].joint.clear();
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

TEST(RosJointGimbal, WholeProtocolReachesDoneAndAFaultAborts) {
  core::GimbalProtocolOptions p;
  p.protocol.steps_per_phase = 4;
  p.protocol.dwell_s = 0.2;
  p.start_delay_s = 0.1;
  p.settle_timeout_s = 20.0;
  for (bool silent_midway : {false, true}) {
    JointController c = controller();
    ai::RosJointGimbal driver(options());
    driver.connect(&c);
    core::GimbalProtocol protocol(p, &driver);
    protocol.start(0.0);
    std::vector<core::GimbalEvent> commands;
    std::string aborted;
    for (int k = 0; k < 120000 && protocol.state() != core::ProtocolState::Done &&
                    protocol.state() != core::ProtocolState::Aborted;
         ++k) {
      const double t = k * 1e-3;
      if (silent_midway && t > 3.0) c.joints[0].silent = true;
      c.step(1e-3);
      if (k % 20 == 0) c.report(t, &driver);
      if (k % 10 == 0) {
        for (const core::ProtocolAction& a : protocol.tick(t)) {
          if (a.kind == core::ProtocolAction::Kind::Command) commands.push_back(a.command);
        }
      }
    }
    if (!silent_midway) {
      ASSERT_EQ(protocol.state(), core::ProtocolState::Done);
      EXPECT_EQ(commands.size(), 2u * 12u + 1u);  // MOVING and SETTLED per position, DONE
    } else {
      ASSERT_EQ(protocol.state(), core::ProtocolState::Aborted);
      const std::string text = protocol.status(200.0).text;
      EXPECT_NE(text.find("outer_joint"), std::string::npos) << text;
    }
  }
}
