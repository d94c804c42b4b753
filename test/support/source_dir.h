// The package's source directory, for tests that read files kept in the repository (examples,
// fuzz corpora, real data). Defined in test/gtest_main.cpp, the one test file compiled with the
// path, so the other test objects do not depend on where the workspace is (ccache shares them).
#pragma once

#include <string>

namespace accel_intrinsics {
namespace test_support {

const std::string& source_dir();

}  // namespace test_support
}  // namespace accel_intrinsics
