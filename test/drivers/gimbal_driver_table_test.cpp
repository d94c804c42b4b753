// The gimbal driver table (docs/design.md section 15): every row reads its own parameters through
// DriverParams (here a map written in the test) and builds its driver; the names are listed.
#include "accel_intrinsics/drivers/gimbal_driver_table.h"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>
#include <variant>

#include "accel_intrinsics/drivers/ros_joint_gimbal.h"

namespace ai = accel_intrinsics;

namespace {

using Value = std::variant<double, int, bool, std::string>;

class MapParams : public ai::DriverParams {
 public:
  std::map<std::string, Value> values;

  std::string name(const std::string& key) const override { return "/gc/" + key; }
  bool has(const std::string& key) const override {
    for (const auto& v : values)
      if (v.first == key || v.first.rfind(key + "/", 0) == 0) return true;
    return false;
  }
  template <typename T>
  bool typed(const std::string& key, T* out) const {
    const auto it = values.find(key);
    if (it == values.end()) return false;
    if (const T* v = std::get_if<T>(&it->second)) {
      *out = *v;
      return true;
    }
    throw std::invalid_argument("parameter " + name(key) + " has the wrong type");
  }
  bool get(const std::string& key, double* v) const override {
    const auto it = values.find(key);
    if (it != values.end() && std::holds_alternative<int>(it->second)) {
      *v = std::get<int>(it->second);
      return true;
    }
    return typed(key, v);
  }
  bool get(const std::string& key, int* v) const override { return typed(key, v); }
  bool get(const std::string& key, bool* v) const override { return typed(key, v); }
  bool get(const std::string& key, std::string* v) const override { return typed(key, v); }
  std::vector<std::string> keys(const std::string& key) const override {
    std::set<std::string> out;
    for (const auto& v : values) {
      if (v.first.rfind(key + "/", 0) != 0) continue;
      const std::string rest = v.first.substr(key.size() + 1);
      out.insert(rest.substr(0, rest.find('/')));
    }
    return std::vector<std::string>(out.begin(), out.end());
  }
  bool get_effects(const std::string&,
                   std::vector<accel_intrinsics::core::Effect>*) const override {
    return false;
  }
};

void grbl_like_map(MapParams* p, const std::string& driver) {
  p->values[driver + "/phases/x/axis"] = std::string("X");
  p->values[driver + "/phases/x/hold/Y"] = 0;
  p->values[driver + "/phases/y/axis"] = std::string("X");
  p->values[driver + "/phases/y/hold/Y"] = 90.0;
  p->values[driver + "/phases/z/axis"] = std::string("Y");
  p->values[driver + "/phases/z/sign"] = -1;
  p->values[driver + "/phases/z/hold/X"] = 90;
}

}  // namespace

TEST(GimbalDriverTable, RowsAndNames) {
  EXPECT_EQ(ai::gimbal_driver_names(), "simulated, grbl, smc100, ros_joint, manual");
  EXPECT_EQ(ai::gimbal_driver_table().front().name, "simulated");
  EXPECT_EQ(ai::find_gimbal_driver("dynamixel"), nullptr);
  ASSERT_NE(ai::find_gimbal_driver("grbl"), nullptr);
  EXPECT_EQ(ai::find_gimbal_driver("grbl")->emulator, "grbl_emulator");
  EXPECT_EQ(ai::find_gimbal_driver("ros_joint")->emulator, "joint_controller_emulator");
  for (const ai::GimbalDriverRow& row : ai::gimbal_driver_table()) {
    EXPECT_TRUE(row.read_options && row.make) << row.name;
    EXPECT_FALSE(row.summary.empty()) << row.name;
  }
}

TEST(GimbalDriverTable, SimulatedNeedsNoParameters) {
  MapParams params;
  const ai::GimbalDriverRow* row = ai::find_gimbal_driver("simulated");
  const std::any o = row->read_options(params, ai::GimbalDriverDefaults{});
  EXPECT_EQ(row->make(o)->name(), "simulated");
}

TEST(GimbalDriverTable, RosJointReadsItsParametersAndBuilds) {
  MapParams params;
  params.values["ros_joint/axes/X/joint"] = std::string("pan");
  params.values["ros_joint/axes/X/command_topic"] = std::string("pan_controller/command");
  params.values["ros_joint/axes/Y/joint"] = std::string("tilt");
  params.values["ros_joint/axes/Y/command_topic"] = std::string("tilt_controller/command");
  params.values["ros_joint/move_timeout_s"] = 12;
  grbl_like_map(&params, "ros_joint");
  const ai::GimbalDriverRow* row = ai::find_gimbal_driver("ros_joint");
  ai::GimbalDriverDefaults defaults;
  defaults.settle_s = 0.7;
  const std::any any = row->read_options(params, defaults);
  const ai::RosJointOptions& o = std::any_cast<const ai::RosJointOptions&>(any);
  EXPECT_EQ(o.joint_states_topic, "joint_states");
  EXPECT_EQ(o.axes.at("Y").joint, "tilt");
  EXPECT_DOUBLE_EQ(o.tolerance_deg, 0.05);
  EXPECT_DOUBLE_EQ(o.settle_s, 0.7);  // the protocol's
  EXPECT_DOUBLE_EQ(o.move_timeout_s, 12.0);
  EXPECT_DOUBLE_EQ(o.axis_map.phases[2].sign, -1.0);
  EXPECT_DOUBLE_EQ(o.axis_map.phases[1].hold.at("Y"), 90.0);
  const std::unique_ptr<ai::GimbalDriver> driver = row->make(any);
  EXPECT_EQ(driver->topics().command_topics.size(), 2u);

  // A phase on an axis that is not a joint, and a missing phase, are named.
  params.values["ros_joint/phases/z/axis"] = std::string("Z");
  try {
    row->read_options(params, defaults);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("/gc/ros_joint/phases.z.axis"), std::string::npos)
        << e.what();
  }
  params.values.erase("ros_joint/phases/z/axis");
  params.values.erase("ros_joint/phases/z/sign");
  params.values.erase("ros_joint/phases/z/hold/X");
  try {
    row->read_options(params, defaults);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("/gc/ros_joint/phases/z"), std::string::npos) << e.what();
  }
}

TEST(GimbalDriverTable, ManualReadsItsToleranceAndAxisMap) {
  MapParams params;
  grbl_like_map(&params, "manual");
  params.values["manual/pose_tolerance_deg"] = 3.0;
  const ai::GimbalDriverRow* row = ai::find_gimbal_driver("manual");
  const std::unique_ptr<ai::GimbalDriver> driver =
      row->make(row->read_options(params, ai::GimbalDriverDefaults{}));
  EXPECT_EQ(driver->topics().imu, "imu/data_raw");
  params.values["manual/pose_tolerance_deg"] = -1.0;
  EXPECT_THROW(row->read_options(params, ai::GimbalDriverDefaults{}), std::invalid_argument);
}
