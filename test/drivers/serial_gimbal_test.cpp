// The serial gimbal drivers (GRBL, SMC100) against their emulators over a real pseudo-terminal:
// moves, settling, the reported orientation, homing, stop, and every injected serial fault,
// whose message must carry the device's own words.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <thread>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/drivers/grbl_driver.h"
#include "accel_intrinsics/drivers/serial_port.h"
#include "accel_intrinsics/drivers/smc100_driver.h"
#include "accel_intrinsics/emulators/emulators.h"

namespace ai = accel_intrinsics;
using ai::core::Phase;

namespace {

double wall_s() {
  static const auto start = std::chrono::steady_clock::now();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Runs an emulator on its own thread for the life of the fixture.
class Served {
 public:
  explicit Served(std::unique_ptr<ai::DeviceEmulator> emulator) : emulator_(std::move(emulator)) {
    thread_ = std::thread([this] { emulator_->run(stop_); });
  }
  ~Served() {
    stop_ = true;
    thread_.join();
  }
  ai::DeviceEmulator& operator*() { return *emulator_; }
  ai::DeviceEmulator* operator->() { return emulator_.get(); }

 private:
  std::unique_ptr<ai::DeviceEmulator> emulator_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// A reply later than this is a fault ("no reply"). Generous, so that a loaded machine's late
// reply is not taken for one; the no_reply cases wait this long.
constexpr double kReplyTimeoutS = 2.0;

// Two-axis map: x and y turn the first axis (y with the second held at 90 deg), z the second.
ai::SerialGimbalOptions two_axis(const std::string& port, const std::string& a,
                                 const std::string& b) {
  ai::SerialGimbalOptions o;
  o.port = port;
  o.reply_timeout_s = kReplyTimeoutS;
  o.poll_interval_s = 0.01;
  o.settle_s = 0.2;
  o.connect_timeout_s = 5.0;
  o.axis_map.phases[0].axis = a;
  o.axis_map.phases[0].hold[b] = 0.0;
  o.axis_map.phases[1].axis = a;
  o.axis_map.phases[1].hold[b] = 90.0;
  o.axis_map.phases[2].axis = b;
  o.axis_map.phases[2].sign = -1.0;
  o.axis_map.phases[2].zero_deg = 10.0;
  o.axis_map.phases[2].hold[a] = 90.0;
  return o;
}

ai::GimbalTarget target(Phase phase, double angle_deg) {
  ai::GimbalTarget t;
  t.phase = phase;
  t.angle_rad = angle_deg * ai::core::kPi / 180.0;
  return t;
}

// Polls until settled (true) or the wall-clock limit (false); faults propagate.
bool wait_settled(ai::GimbalDriver& driver, double limit_s = 10.0) {
  const double end = wall_s() + limit_s;
  while (wall_s() < end) {
    driver.update(wall_s());
    if (driver.settled(wall_s())) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// The message of the GimbalFault a move (and the wait for it) raises; "" when none.
std::string fault_of_move(ai::GimbalDriver& driver, const ai::GimbalTarget& t) {
  try {
    driver.move_to(t, wall_s());
    wait_settled(driver, 30.0);
  } catch (const ai::GimbalFault& e) {
    return e.what();
  }
  return "";
}

double reported_alpha_deg(const ai::GimbalDriver& driver, Phase phase) {
  // Recover alpha from the broadcast orientation: the DUT's specific force is eq. (4).
  const Eigen::Matrix3d R = driver.orientation(wall_s()).world_dut();
  const Eigen::Vector3d f = R.transpose() * Eigen::Vector3d::UnitZ();
  switch (phase) {
    case Phase::X: return std::atan2(f.y(), f.z()) * 180.0 / ai::core::kPi;
    case Phase::Y: return std::atan2(f.x(), f.z()) * 180.0 / ai::core::kPi;
    default: return std::atan2(f.x(), f.y()) * 180.0 / ai::core::kPi;
  }
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

ai::EmulatorOptions fast() {
  ai::EmulatorOptions e;
  e.rate_deg_s = 900.0;
  e.home_s = 0.2;
  return e;
}

}  // namespace

TEST(AxisMap, PositionsAndAlphaRoundTrip) {
  const ai::AxisMap map = two_axis("p", "X", "Y").axis_map;
  const auto z = map.positions_deg(Phase::Z, 30.0 * ai::core::kPi / 180.0);
  EXPECT_NEAR(z.at("Y"), 10.0 - 30.0, 1e-12);
  EXPECT_NEAR(z.at("X"), 90.0, 1e-12);
  EXPECT_NEAR(map.alpha_rad(Phase::Z, -20.0), 30.0 * ai::core::kPi / 180.0, 1e-12);
  EXPECT_NO_THROW(map.validate({"X", "Y", "Z"}));
}

TEST(AxisMap, OneAxisStageNeedsManualRemount) {
  ai::AxisMap map;
  for (auto& p : map.phases) p.axis = "1";
  try {
    map.validate({});
    FAIL() << "accepted three phases on one axis without a remount";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("phases.y.manual_remount"), std::string::npos) << e.what();
  }
  map.phases[1].manual_remount = map.phases[2].manual_remount = true;
  EXPECT_NO_THROW(map.validate({}));
  map.phases[0].sign = 2.0;
  EXPECT_THROW(map.validate({}), std::invalid_argument);
}

TEST(Grbl, ParsesStatusReports) {
  ai::GrblStatus s;
  ASSERT_TRUE(
      ai::parse_grbl_status("<Hold:0|MPos:1.000,-2.500,3.000|FS:0,0|WCO:0.000,1.000,0.000>", &s));
  EXPECT_EQ(s.state, "Hold");
  EXPECT_EQ(s.full_state, "Hold:0");
  ASSERT_EQ(s.mpos.size(), 3u);
  EXPECT_DOUBLE_EQ(s.mpos[1], -2.5);
  EXPECT_DOUBLE_EQ(s.wco[1], 1.0);
  EXPECT_FALSE(ai::parse_grbl_status("<Bogus|MPos:1,2,3>", &s));
  EXPECT_FALSE(ai::parse_grbl_status("<Idle|MPos:1,x,3>", &s));
  EXPECT_FALSE(ai::parse_grbl_status("Idle|MPos:1,2,3", &s));
}

TEST(Grbl, MovesSettlesAndReportsThePosition) {
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(fast())));
  ai::GrblDriver driver(two_axis(emu->port(), "X", "Y"));
  for (const auto& step : {std::make_pair(Phase::X, 90.0), std::make_pair(Phase::Y, 45.0),
                           std::make_pair(Phase::Z, 120.0)}) {
    const double t0 = wall_s();
    driver.move_to(target(step.first, step.second), t0);
    ASSERT_TRUE(wait_settled(driver)) << driver.status_text();
    // At rest at the target for settle_s before SETTLED.
    EXPECT_GE(driver.settled_at(wall_s()), t0 + 0.2);
    EXPECT_NEAR(reported_alpha_deg(driver, step.first), step.second, 0.01);
  }
  const auto commands = emu->commands();
  ASSERT_FALSE(commands.empty());
  EXPECT_EQ(commands.front(), "^X");  // soft reset at start
  EXPECT_TRUE(contains(commands, "G21 G90 G0 X90.0000 Y0.0000"));
  EXPECT_TRUE(contains(commands, "G21 G90 G0 X45.0000 Y90.0000"));
  EXPECT_TRUE(contains(commands, "G21 G90 G0 X90.0000 Y-110.0000"));
  for (const std::string& c : commands) {
    EXPECT_TRUE(c == "?" || c == "^X" || c.rfind("G21 G90 G0 ", 0) == 0) << "unexpected: " << c;
  }
}

TEST(Grbl, ReportsTheMotionWhileMoving) {
  // A 3 s move; polled until the motion shows (no fixed sleep), which must then be mid-way: a
  // report of 2 to 85 deg, unless the poll loop stalled for 2.7 s.
  ai::EmulatorOptions e = fast();
  e.rate_deg_s = 30.0;
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(e)));
  ai::GrblDriver driver(two_axis(emu->port(), "X", "Y"));
  driver.move_to(target(Phase::X, 90.0), wall_s());
  double mid = 0.0;
  for (const double end = wall_s() + 30.0; wall_s() < end;) {
    driver.update(wall_s());
    mid = reported_alpha_deg(driver, Phase::X);
    if (mid > 2.0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_FALSE(driver.settled(wall_s()));
  EXPECT_GT(mid, 2.0);
  EXPECT_LT(mid, 85.0);
  ASSERT_TRUE(wait_settled(driver, 30.0));
}

// The stage rests until the move command goes out: the orientation reported for any instant
// before it is the rest position, however late the first poll in motion comes (stamps here are
// the node clock's, 100 s ahead of the wall clock the settling used). Before, the orientation
// interpolated from the last rest poll toward the first position polled in motion, so the tf the
// controller fills in up to a MOVING stamp showed the move early.
TEST(Grbl, ReportsNoMotionBeforeTheMoveCommand) {
  ai::EmulatorOptions e = fast();
  e.rate_deg_s = 1.0e6;  // the move is over before the poll that follows the command
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(e)));
  ai::GrblDriver driver(two_axis(emu->port(), "X", "Y"));
  driver.move_to(target(Phase::X, 0.0), wall_s());
  ASSERT_TRUE(wait_settled(driver));
  auto alpha_at = [&](double t_s) {
    const Eigen::Vector3d f =
        driver.orientation(t_s).world_dut().transpose() * Eigen::Vector3d::UnitZ();
    return std::atan2(f.y(), f.z()) * 180.0 / ai::core::kPi;
  };
  const double rest_s = wall_s() + 100.0;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  driver.update(rest_s);  // polled at rest
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double command_s = rest_s + 1.0;
  driver.move_to(target(Phase::X, 90.0), command_s);
  // Polled (stamps 0.1 s after the command on, 1 us apart) until the move shows, bounded.
  double seen_s = command_s + 0.1;
  for (int k = 0; k < 10000; ++k) {
    seen_s = command_s + 0.1 + 1e-6 * k;
    driver.update(seen_s);
    if (std::abs(alpha_at(seen_s) - 90.0) < 0.01) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_NEAR(alpha_at(seen_s), 90.0, 0.01);  // the move was seen
  for (double t : {rest_s, rest_s + 0.5, command_s - 1e-6}) {
    EXPECT_NEAR(alpha_at(t), 0.0, 1e-9) << "at " << t - command_s << " s from the command";
  }
  // A phase change: until its command the DUT keeps the frame of the phase it is in. (Settled
  // on the node clock's stamps: 0.2 s at rest, settle_s.)
  for (int k = 0; k < 1000 && !driver.settled(command_s + 0.1); ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(15));
    driver.update(seen_s + 0.01 * k);
  }
  ASSERT_TRUE(driver.settled(command_s + 1.5));
  const double z_command_s = command_s + 2.0;
  driver.update(z_command_s - 0.5);
  driver.move_to(target(Phase::Z, 30.0), z_command_s);
  for (int k = 0; k < 10000; ++k) {
    driver.update(z_command_s + 0.1);
    if ((driver.orientation(z_command_s + 0.1).world_dut() -
         ai::gimbal_transforms(Phase::Z, 30.0 * ai::core::kPi / 180.0, 0.0).world_dut())
            .norm() < 1e-6)
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const Eigen::Matrix3d before_x =
      ai::gimbal_transforms(Phase::X, 90.0 * ai::core::kPi / 180.0, 0.0).world_dut();
  const Eigen::Matrix3d after_z =
      ai::gimbal_transforms(Phase::Z, 30.0 * ai::core::kPi / 180.0, 0.0).world_dut();
  for (double t : {z_command_s - 0.4, z_command_s - 1e-6}) {
    EXPECT_LT((driver.orientation(t).world_dut() - before_x).norm(), 1e-9)
        << "at " << t - z_command_s << " s from the command";
  }
  EXPECT_LT((driver.orientation(z_command_s + 0.1).world_dut() - after_z).norm(), 1e-6);
}

TEST(Grbl, HomesAtStartOrRefusesAnAlarm) {
  ai::EmulatorOptions e = fast();
  e.needs_homing = true;
  {
    Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(e)));
    try {
      ai::GrblDriver driver(two_axis(emu->port(), "X", "Y"));
      FAIL() << "started on a controller in alarm";
    } catch (const ai::GimbalFault& f) {
      EXPECT_NE(std::string(f.what()).find("alarm at start"), std::string::npos) << f.what();
    }
  }
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(e)));
  ai::SerialGimbalOptions o = two_axis(emu->port(), "X", "Y");
  o.home_at_start = true;
  ai::GrblDriver driver(o);
  EXPECT_TRUE(contains(emu->commands(), "$H"));
  driver.move_to(target(Phase::X, 30.0), wall_s());
  EXPECT_TRUE(wait_settled(driver));
}

TEST(Grbl, StopHoldsThenResetsAndKeepsWorking) {
  ai::EmulatorOptions e = fast();
  e.rate_deg_s = 60.0;
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(e)));
  ai::GrblDriver driver(two_axis(emu->port(), "X", "Y"));
  driver.move_to(target(Phase::X, 180.0), wall_s());
  // Stopped once the motion shows (a 3 s move), not after a fixed sleep.
  for (const double end = wall_s() + 30.0; wall_s() < end;) {
    driver.update(wall_s());
    if (reported_alpha_deg(driver, Phase::X) > 1.0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_FALSE(driver.settled(wall_s()));
  driver.stop(wall_s());
  const auto commands = emu->commands();
  const auto hold = std::find(commands.begin(), commands.end(), "!");
  ASSERT_NE(hold, commands.end());
  EXPECT_NE(std::find(hold, commands.end(), "^X"), commands.end());
  driver.move_to(target(Phase::X, 10.0), wall_s());
  EXPECT_TRUE(wait_settled(driver)) << driver.status_text();
}

struct FaultCase {
  std::string fault;
  std::vector<std::string> words;  // in the message
};

// The emulator injects `c.fault` at the second move: the first move is fine, the second's fault
// message carries `c.words`, and stop() never throws, whatever the device does.
template <class Emulator, class Driver>
void expect_second_move_fault(const FaultCase& c,
                              ai::SerialGimbalOptions (*options)(const std::string& port)) {
  ai::EmulatorOptions e = fast();
  e.fault = c.fault;
  e.fault_after = 1;
  e.rate_deg_s = 180.0;
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new Emulator(e)));
  Driver driver(options(emu->port()));
  ASSERT_EQ(fault_of_move(driver, target(Phase::X, 30.0)), "");
  const std::string message = fault_of_move(driver, target(Phase::X, 90.0));
  ASSERT_FALSE(message.empty()) << "no fault for " << c.fault;
  for (const std::string& w : c.words) {
    EXPECT_NE(message.find(w), std::string::npos) << "'" << w << "' not in: " << message;
  }
  driver.stop(wall_s());
}

ai::SerialGimbalOptions two_axis_grbl(const std::string& port) {
  return two_axis(port, "X", "Y");
}

class GrblFault : public testing::TestWithParam<FaultCase> {};

TEST_P(GrblFault, CarriesTheDevicesWords) {
  expect_second_move_fault<ai::GrblEmulator, ai::GrblDriver>(GetParam(), two_axis_grbl);
}

INSTANTIATE_TEST_SUITE_P(
    Serial, GrblFault,
    testing::Values(FaultCase{"error", {"error:20", "G21 G90 G0 X90.0000", "Unsupported"}},
                    FaultCase{"alarm", {"ALARM:1", "Hard limit"}},
                    FaultCase{"garbage", {"unexpected reply", "\\x07#~q"}},
                    FaultCase{"no_reply", {"no reply", "G21 G90 G0 X90.0000"}},
                    FaultCase{"vanish", {"lost"}}),
    [](const testing::TestParamInfo<FaultCase>& info) { return info.param.fault; });

TEST(Smc100, HomesMovesSettlesAndReportsThePosition) {
  ai::EmulatorOptions e = fast();
  e.addresses = {1, 2};
  e.needs_homing = true;
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::Smc100Emulator(e)));
  ai::SerialGimbalOptions o = two_axis(emu->port(), "1", "2");
  o.baud = 57600;
  {
    ai::SerialGimbalOptions no_home = o;
    try {
      ai::Smc100Driver driver(no_home);
      FAIL() << "started on NOT REFERENCED controllers";
    } catch (const ai::GimbalFault& f) {
      EXPECT_NE(std::string(f.what()).find("1TS00000A"), std::string::npos) << f.what();
      EXPECT_NE(std::string(f.what()).find("NOT REFERENCED"), std::string::npos) << f.what();
    }
  }
  o.home_at_start = true;
  ai::Smc100Driver driver(o);
  EXPECT_TRUE(contains(emu->commands(), "1OR"));
  EXPECT_TRUE(contains(emu->commands(), "2OR"));
  for (const auto& step : {std::make_pair(Phase::X, 90.0), std::make_pair(Phase::Z, 200.0)}) {
    driver.move_to(target(step.first, step.second), wall_s());
    ASSERT_TRUE(wait_settled(driver)) << driver.status_text();
    EXPECT_NEAR(reported_alpha_deg(driver, step.first),
                step.second > 180.0 ? step.second - 360.0 : step.second, 0.01);
  }
  const auto commands = emu->commands();
  EXPECT_TRUE(contains(commands, "1PA90.0000"));
  EXPECT_TRUE(contains(commands, "2PA0.0000"));
  EXPECT_TRUE(contains(commands, "2PA-190.0000"));
  for (const std::string& c : commands) {
    const std::string body = c.substr(1);
    EXPECT_TRUE(body == "TS?" || body == "TP?" || body == "TE?" || body == "OR" ||
                body.rfind("PA", 0) == 0)
        << "unexpected: " << c;
  }
}

// One SMC100 at address 1 turning every phase (y and z remounted by hand).
ai::SerialGimbalOptions one_axis_smc100(const std::string& port) {
  ai::SerialGimbalOptions o;
  o.port = port;
  o.baud = 57600;
  o.xon_xoff = true;
  o.reply_timeout_s = kReplyTimeoutS;
  o.poll_interval_s = 0.01;
  o.settle_s = 0.1;
  for (int p = 0; p < 3; ++p) {
    o.axis_map.phases[p].axis = "1";
    o.axis_map.phases[p].manual_remount = p > 0;
  }
  return o;
}

class Smc100Fault : public testing::TestWithParam<FaultCase> {};

TEST_P(Smc100Fault, CarriesTheDevicesWords) {
  expect_second_move_fault<ai::Smc100Emulator, ai::Smc100Driver>(GetParam(), one_axis_smc100);
}

INSTANTIATE_TEST_SUITE_P(
    Serial, Smc100Fault,
    testing::Values(FaultCase{"error", {"1TEG", "displacement out of limits", "1PA90.0000"}},
                    FaultCase{"alarm", {"1TS00203D", "following error", "DISABLE from MOVING"}},
                    FaultCase{"garbage", {"unexpected reply", "\\x07#~q"}},
                    FaultCase{"no_reply", {"no reply", "1TE?"}}, FaultCase{"vanish", {"lost"}}),
    [](const testing::TestParamInfo<FaultCase>& info) { return info.param.fault; });

// A controller written here from Newport's SMC100CC/PP manual, independently of Smc100Emulator:
// set commands are silent; TE answers the letter of the last command's error, '@' for none (A:
// unknown message code, C: parameter missing or out of range, ...); TS answers "1TS", 4 hex digits
// of positioner errors and 2 of the controller state (32 READY from HOMING, 33 READY from
// MOVING). `refuse` is the TE letter its PA leaves ('@': the move is done at once).
class ManualSmc100 : public ai::DeviceEmulator {
 public:
  explicit ManualSmc100(char refuse) : DeviceEmulator(ai::EmulatorOptions()), refuse_(refuse) {}

 protected:
  void on_line(const std::string& line) override {
    if (line == "1TS?") {
      reply(moved_ ? "1TS000033\r\n" : "1TS000032\r\n");
    } else if (line == "1TP?") {
      reply(moved_ ? "1TP90\r\n" : "1TP0\r\n");
    } else if (line == "1TE?") {
      reply(std::string("1TE") + error_ + "\r\n");
      error_ = '@';
    } else if (line.rfind("1PA", 0) == 0) {
      error_ = refuse_;
      moved_ = refuse_ == '@';
    } else {
      error_ = 'A';
    }
  }
  void on_time() override {}

 private:
  char refuse_;
  char error_ = '@';
  bool moved_ = false;
};

// Whether the terminal at `path` has XON/XOFF flow control on both ways (termios settings
// belong to the terminal, so a second descriptor sees what the driver set).
bool xon_xoff_on(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
  EXPECT_GE(fd, 0) << path;
  termios tio{};
  const bool read = fd >= 0 && tcgetattr(fd, &tio) == 0;
  if (fd >= 0) ::close(fd);
  return read && (tio.c_iflag & (IXON | IXOFF)) == (IXON | IXOFF);
}

TEST(SerialPort, XonXoffOnlyWhenAsked) {
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(fast())));
  for (bool flow : {true, false, true}) {
    ai::SerialPort port;
    port.open(emu->port(), 57600, flow);
    EXPECT_EQ(xon_xoff_on(emu->port()), flow);
  }
}

TEST(Smc100, TakesTheManualsNoErrorAndNamesItsErrorLetters) {
  {
    Served device(std::unique_ptr<ai::DeviceEmulator>(new ManualSmc100('@')));
    ai::Smc100Driver driver(one_axis_smc100(device->port()));
    EXPECT_TRUE(xon_xoff_on(device->port()));  // the manual's RS-232-C settings
    EXPECT_EQ(fault_of_move(driver, target(Phase::X, 90.0)), "");
    EXPECT_TRUE(driver.settled(wall_s()));
    EXPECT_NEAR(reported_alpha_deg(driver, Phase::X), 90.0, 1e-9);
  }
  for (const auto& refusal : {std::make_pair('C', "parameter missing or out of range"),
                              std::make_pair('A', "unknown message code"),
                              std::make_pair('H', "not allowed in NOT REFERENCED state")}) {
    Served device(std::unique_ptr<ai::DeviceEmulator>(new ManualSmc100(refusal.first)));
    ai::Smc100Driver driver(one_axis_smc100(device->port()));
    const std::string message = fault_of_move(driver, target(Phase::X, 90.0));
    EXPECT_NE(message.find(std::string("1TE") + refusal.first), std::string::npos) << message;
    EXPECT_NE(message.find(refusal.second), std::string::npos) << message;
  }
}

// The manual: spaces anywhere are ignored and commands are not case-sensitive; an unknown
// command is TE error A, a PA without a number C, a second OR while homing E.
TEST(Smc100, EmulatorReadsLinesAndReportsErrorsAsTheManualSays) {
  ai::EmulatorOptions e = fast();
  e.needs_homing = true;
  e.home_s = 5.0;
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::Smc100Emulator(e)));
  ai::SerialPort port;
  port.open(emu->port(), 57600);
  auto ask = [&](const std::string& line) {
    port.write(line + "\r\n");
    std::string reply;
    EXPECT_TRUE(port.read_line(&reply, 1.0)) << "no reply to " << line;
    return reply;
  };
  EXPECT_EQ(ask("1 ts ?"), "1TS00000A");
  EXPECT_EQ(ask("1TE?"), "1TE@");
  port.write("1XX\r\n");
  EXPECT_EQ(ask("1TE?"), "1TEA");
  port.write("1or\r\n");
  EXPECT_EQ(ask("1TE?"), "1TE@");
  EXPECT_EQ(ask("1TS?"), "1TS00001E");
  port.write("1OR\r\n");
  EXPECT_EQ(ask("1TE?"), "1TEE");
  port.write("1PA\r\n");
  EXPECT_EQ(ask("1TE?"), "1TEC");
}

TEST(SerialPort, MissingPortSaysSo) {
  ai::SerialGimbalOptions o = two_axis("/nonexistent/ttyACM9", "X", "Y");
  o.connect_timeout_s = 0.0;
  try {
    ai::GrblDriver driver(o);
    FAIL() << "opened a missing port";
  } catch (const ai::GimbalFault& f) {
    EXPECT_NE(std::string(f.what()).find("/nonexistent/ttyACM9"), std::string::npos) << f.what();
    EXPECT_NE(std::string(f.what()).find("No such file"), std::string::npos) << f.what();
  }
}

// A node started with stdin closed opens its port as file descriptor 0, a valid descriptor:
// the port must work there. fd 0 is freed here (and restored after) so that the open takes it.
TEST(SerialPort, WorksOnFileDescriptorZero) {
  int device = -1, port_side = -1;
  char name[256] = {0};
  ASSERT_EQ(openpty(&device, &port_side, name, nullptr, nullptr), 0);
  const int saved_stdin = ::dup(0);
  ::close(0);
  std::string reply, error;
  char received[8] = {0};
  try {
    ai::SerialPort port;
    port.open(name, 115200);
    EXPECT_EQ(::fcntl(0, F_GETFD), FD_CLOEXEC) << "the port did not take fd 0";
    port.write("?\n");
    for (int k = 0; k < 100 && ::read(device, received, 1) != 1; ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ASSERT_EQ(::write(device, "ok\r\n", 4), 4);
    port.read_line(&reply, 1.0);
  } catch (const std::exception& ex) {
    error = ex.what();
  }
  if (saved_stdin >= 0) {
    ::dup2(saved_stdin, 0);
    ::close(saved_stdin);
  }
  ::close(device);
  ::close(port_side);
  EXPECT_EQ(error, "");
  EXPECT_EQ(received[0], '?');
  EXPECT_EQ(reply, "ok");
}

namespace {
// A GRBL that must be homed and raises ALARM:1 on its first move.
ai::EmulatorOptions alarm_on_first_move() {
  ai::EmulatorOptions e = fast();
  e.needs_homing = true;
  e.fault = "alarm";
  e.fault_after = 0;
  return e;
}
}  // namespace

TEST(Recover, GrblAlarmIsHomedAwayAndTheStageMovesAgain) {
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(alarm_on_first_move())));
  ai::SerialGimbalOptions o = two_axis(emu->port(), "X", "Y");
  o.home_at_start = true;
  ai::GrblDriver driver(o);
  EXPECT_NE(fault_of_move(driver, target(Phase::X, 120.0)).find("ALARM:1"), std::string::npos);
  driver.recover(wall_s());
  const auto commands = emu->commands();
  EXPECT_EQ(std::count(commands.begin(), commands.end(), "^X"), 2);
  EXPECT_EQ(std::count(commands.begin(), commands.end(), "$H"), 2);
  EXPECT_EQ(fault_of_move(driver, target(Phase::X, 120.0)), "");
  EXPECT_NEAR(reported_alpha_deg(driver, Phase::X), 120.0, 0.01);
}

// After a recovery the stage is where the device says (homed: 0 deg), not at the target of
// the move that faulted: the first update reads the device, however recent the faulted poll.
TEST(Recover, TheFirstUpdateAfterARecoveryReportsTheHomedStage) {
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(alarm_on_first_move())));
  ai::SerialGimbalOptions o = two_axis(emu->port(), "X", "Y");
  o.home_at_start = true;
  o.poll_interval_s = 2.0;  // the recovery (0.2 s homing) is over well within one interval
  ai::GrblDriver driver(o);
  EXPECT_NE(fault_of_move(driver, target(Phase::X, 120.0)).find("ALARM:1"), std::string::npos);
  driver.recover(wall_s());
  driver.update(wall_s());
  EXPECT_NEAR(reported_alpha_deg(driver, Phase::X), 0.0, 0.01);
}

TEST(Recover, GrblAlarmIsUnlockedOnlyWhenConfigured) {
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(alarm_on_first_move())));
  ai::SerialGimbalOptions o = two_axis(emu->port(), "X", "Y");
  o.unlock_at_start = true;
  ai::GrblDriver driver(o);
  EXPECT_TRUE(contains(emu->commands(), "$X"));
  EXPECT_NE(fault_of_move(driver, target(Phase::X, 120.0)).find("ALARM:1"), std::string::npos);
  EXPECT_NO_THROW(driver.recover(wall_s()));  // unlock_at_start: $X again
  const auto commands = emu->commands();
  EXPECT_EQ(std::count(commands.begin(), commands.end(), "$X"), 2);
  EXPECT_EQ(fault_of_move(driver, target(Phase::X, 60.0)), "");

  // Neither homing nor unlocking allowed: the recovery fails and says what to do.
  Served emu2(std::unique_ptr<ai::DeviceEmulator>(new ai::GrblEmulator(alarm_on_first_move())));
  ai::SerialGimbalOptions o2 = two_axis(emu2->port(), "X", "Y");
  o2.home_at_start = true;
  ai::GrblDriver driver2(o2);
  EXPECT_FALSE(fault_of_move(driver2, target(Phase::X, 120.0)).empty());
  ai::SerialGimbalOptions o3 = o2;
  o3.home_at_start = false;
  ai::GrblDriver* bare = nullptr;
  try {
    bare = new ai::GrblDriver(o3);  // a fresh driver on the alarmed controller
    FAIL() << "started on a controller in alarm";
  } catch (const ai::GimbalFault& f) {
    EXPECT_NE(std::string(f.what()).find("home_at_start"), std::string::npos) << f.what();
    EXPECT_NE(std::string(f.what()).find("unlock_at_start"), std::string::npos) << f.what();
  }
  delete bare;
}

TEST(Recover, Smc100FollowingErrorIsResetAndHomed) {
  ai::EmulatorOptions e = fast();
  e.needs_homing = true;
  e.fault = "alarm";
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::Smc100Emulator(e)));
  ai::SerialGimbalOptions o;
  o.port = emu->port();
  o.baud = 57600;
  o.reply_timeout_s = kReplyTimeoutS;
  o.poll_interval_s = 0.01;
  o.settle_s = 0.1;
  o.home_at_start = true;
  for (int p = 0; p < 3; ++p) {
    o.axis_map.phases[p].axis = "1";
    o.axis_map.phases[p].manual_remount = p > 0;
  }
  ai::Smc100Driver driver(o);
  EXPECT_NE(fault_of_move(driver, target(Phase::X, 90.0)).find("following error"),
            std::string::npos);
  driver.recover(wall_s());
  const auto commands = emu->commands();
  EXPECT_TRUE(contains(commands, "1RS"));
  EXPECT_EQ(std::count(commands.begin(), commands.end(), "1OR"), 2);
  EXPECT_EQ(fault_of_move(driver, target(Phase::X, 90.0)), "");
  EXPECT_NEAR(reported_alpha_deg(driver, Phase::X), 90.0, 0.01);
}

TEST(Recover, Smc100WithoutHomingSaysWhatToDo) {
  ai::EmulatorOptions e = fast();
  e.fault = "alarm";
  Served emu(std::unique_ptr<ai::DeviceEmulator>(new ai::Smc100Emulator(e)));
  ai::SerialGimbalOptions o;
  o.port = emu->port();
  o.reply_timeout_s = kReplyTimeoutS;
  o.poll_interval_s = 0.01;
  o.settle_s = 0.1;
  for (int p = 0; p < 3; ++p) {
    o.axis_map.phases[p].axis = "1";
    o.axis_map.phases[p].manual_remount = p > 0;
  }
  ai::Smc100Driver driver(o);
  EXPECT_FALSE(fault_of_move(driver, target(Phase::X, 90.0)).empty());
  try {
    driver.recover(wall_s());
    FAIL() << "recovered a DISABLEd controller without being allowed to reset it";
  } catch (const ai::GimbalFault& f) {
    EXPECT_NE(std::string(f.what()).find("DISABLE from MOVING"), std::string::npos) << f.what();
  }
}
