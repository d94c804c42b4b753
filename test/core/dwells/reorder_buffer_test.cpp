// The assembler's reorder buffer (docs/design.md section 2; docs/noise.md "Where the calibration
// node's memory goes"): the order it releases events in, against an order computed here from
// the rule alone (stamp, then commands before everything else at equal stamps, then arrival),
// and what a buffer of in-order samples costs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"

namespace core = accel_intrinsics::core;

namespace {

enum class Kind { Command, Sample, Reading };

// One message as the test sends it; `id` identifies it in what the assembler releases (a
// command's step, a sample's first output, a reading's value).
struct Message {
  Kind kind;
  double stamp_s;
  std::uint32_t id;
  double value = 0.0;  // a sample's outputs are (id, value, -id): equal stamps, other values
};

// What an observer saw: the kind and the id.
using Seen = std::pair<Kind, std::uint32_t>;

// The release order from the rule, not from the assembler: messages in arrival order, sorted by
// (stamp, commands first, arrival index); then a sample whose stamp equals the previous
// released sample's is not passed on (a duplicate or a conflicting copy: the first to arrive
// wins), as the assembler's sample observer documents.
std::vector<Seen> reference_order(const std::vector<Message>& arrivals) {
  std::vector<std::size_t> index(arrivals.size());
  for (std::size_t i = 0; i < index.size(); ++i) index[i] = i;
  std::sort(index.begin(), index.end(), [&](std::size_t a, std::size_t b) {
    const Message& x = arrivals[a];
    const Message& y = arrivals[b];
    return std::make_tuple(x.stamp_s, x.kind == Kind::Command ? 0 : 1, a) <
           std::make_tuple(y.stamp_s, y.kind == Kind::Command ? 0 : 1, b);
  });
  std::vector<Seen> order;
  bool have_sample = false;
  double last_sample_s = 0.0;
  for (std::size_t i : index) {
    const Message& m = arrivals[i];
    if (m.kind == Kind::Sample) {
      if (have_sample && m.stamp_s == last_sample_s) continue;
      have_sample = true;
      last_sample_s = m.stamp_s;
    }
    order.push_back({m.kind, m.id});
  }
  return order;
}

// Feeds `arrivals` in their order, flushes, and returns what the observers saw.
std::vector<Seen> released_order(const std::vector<Message>& arrivals, double window_s,
                                 core::AssemblerCounters* counters = nullptr) {
  core::AssemblerOptions options;
  options.reorder_window_s = window_s;
  core::DwellAssembler assembler(options);
  std::vector<Seen> seen;
  assembler.set_release_observers(
      [&](const core::GimbalEvent& c) {
        seen.push_back({Kind::Command, c.step});
      },
      [&](const core::ImuSample& s) {
        seen.push_back({Kind::Sample, static_cast<std::uint32_t>(s.outputs.x())});
      });
  assembler.set_channel_observer([&](const core::ChannelSample& r) {
    seen.push_back({Kind::Reading, static_cast<std::uint32_t>(r.value)});
  });
  for (const Message& m : arrivals) {
    switch (m.kind) {
      case Kind::Command: {
        core::GimbalEvent c;
        c.stamp_s = m.stamp_s;
        c.step = m.id;
        c.steps = 4;
        c.state = m.id % 2 == 0 ? core::GimbalState::Moving : core::GimbalState::Settled;
        assembler.add_command(c);
        break;
      }
      case Kind::Sample: {
        core::ImuSample s;
        s.stamp_s = m.stamp_s;
        s.outputs = Eigen::Vector3d(m.id, m.value, -static_cast<double>(m.id));
        assembler.add_sample(s);
        break;
      }
      case Kind::Reading:
        assembler.add_channel_sample(
            core::ChannelSample{core::Channel::Temperature, m.stamp_s, static_cast<double>(m.id)});
        break;
    }
  }
  assembler.flush();
  EXPECT_EQ(assembler.buffered_events(), 0u);
  if (counters) *counters = assembler.counters();
  return seen;
}

std::string describe(const std::vector<Seen>& order) {
  std::string s;
  for (const Seen& e : order) {
    s += e.first == Kind::Command ? 'c' : e.first == Kind::Sample ? 's' : 'r';
    s += std::to_string(e.second) + ' ';
  }
  return s;
}

}  // namespace

TEST(DwellAssemblerReorder, HandWrittenEqualStampsAndARunBrokenByALateArrival) {
  using K = Kind;
  // Arrival order as written. Samples 1..3 in order (one run), sample 4 (t = 0.015) arrives
  // after sample 5 (t = 0.02, already buffered): the heap, and the run of samples after it
  // starts anew; at t = 0.03 a sample, a reading and a copy of the sample arrive before the
  // command with that stamp, which must still go first; sample 9 repeats 8's stamp with other
  // values (the first to arrive is the one used); a reading and a command share t = 0.04 and
  // arrive in the opposite order to the rule's.
  const std::vector<Message> arrivals = {
      {K::Command, 0.0, 0},    {K::Sample, 0.0, 1},     {K::Sample, 0.01, 2},
      {K::Reading, 0.01, 3},   {K::Sample, 0.02, 5},    {K::Sample, 0.015, 4},
      {K::Sample, 0.025, 6},   {K::Sample, 0.03, 8, 1}, {K::Reading, 0.03, 7},
      {K::Sample, 0.03, 8, 1}, {K::Sample, 0.03, 9, 2}, {K::Command, 0.03, 1},
      {K::Reading, 0.04, 10},  {K::Sample, 0.04, 11},   {K::Command, 0.04, 2},
      {K::Sample, 0.05, 12}};
  const std::vector<Seen> expected = reference_order(arrivals);
  // The rule, spelled out for this stream (also a check of reference_order itself).
  const std::vector<Seen> by_hand = {
      {K::Command, 0}, {K::Sample, 1},   {K::Sample, 2},  {K::Reading, 3}, {K::Sample, 4},
      {K::Sample, 5},  {K::Sample, 6},   {K::Command, 1}, {K::Sample, 8},  {K::Reading, 7},
      {K::Command, 2}, {K::Reading, 10}, {K::Sample, 11}, {K::Sample, 12}};
  ASSERT_EQ(describe(expected), describe(by_hand));
  core::AssemblerCounters counters;
  EXPECT_EQ(describe(released_order(arrivals, 0.025, &counters)), describe(expected));
  EXPECT_EQ(counters.duplicates, 1u);
  EXPECT_EQ(counters.dropped_backwards, 1u);
  EXPECT_EQ(counters.dropped_late, 0u);
}

TEST(DwellAssemblerReorder, RandomStreamsWithCopiesAndLateArrivalsReleaseInTheRulesOrder) {
  // Stamps on a 1 ms grid, several messages per stamp (samples, copies of them with the same
  // or other values, readings, now and then a command), in a random order at each stamp; one in
  // eight arrives up to 0.4 window late (never past the window: nothing is dropped late).
  const double window_s = 0.02;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<std::pair<double, Message>> sent;  // (arrival time, message)
    std::uint32_t next_id = 0;
    auto send = [&](const Message& m) {
      const double delay = u(rng) < 0.125 ? 0.4 * window_s * u(rng) : 0.0;
      sent.push_back({m.stamp_s + delay, m});
    };
    for (int k = 0; k < 400; ++k) {
      const double t = 0.001 * k;
      std::vector<Message> at_t;
      const std::uint32_t sample_id = next_id++;
      at_t.push_back({Kind::Sample, t, sample_id, 0.5});
      if (u(rng) < 0.2) at_t.push_back({Kind::Sample, t, sample_id, 0.5});   // a copy
      if (u(rng) < 0.1) at_t.push_back({Kind::Sample, t, next_id++, 0.75});  // other values
      if (u(rng) < 0.3) at_t.push_back({Kind::Reading, t, next_id++});
      if (u(rng) < 0.05) at_t.push_back({Kind::Command, t, next_id++});
      std::shuffle(at_t.begin(), at_t.end(), rng);
      for (const Message& m : at_t) send(m);
    }
    std::stable_sort(sent.begin(), sent.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<Message> arrivals;
    for (const auto& s : sent) arrivals.push_back(s.second);
    core::AssemblerCounters counters;
    const std::vector<Seen> released = released_order(arrivals, window_s, &counters);
    EXPECT_EQ(counters.dropped_late, 0u) << seed;
    ASSERT_EQ(describe(released), describe(reference_order(arrivals))) << "seed " << seed;
  }
}

TEST(DwellAssemblerReorder, BufferedInOrderSamplesCostAtMost34BytesEach) {
  // A full reorder window of in-order samples at 10 kHz, with a command at the start and a
  // temperature reading every 10 ms (each breaks the run of samples): memory_bytes() per
  // buffered sample (the whole Event with its variant cost 64 bytes).
  core::AssemblerOptions options;
  options.reorder_window_s = 0.25;
  core::DwellAssembler assembler(options);
  const std::size_t empty = assembler.memory_bytes();
  core::GimbalEvent settled;
  settled.stamp_s = 0.0;
  settled.state = core::GimbalState::Settled;
  assembler.add_command(settled);
  std::size_t samples = 0;
  for (int i = 0; i < 2400; ++i) {
    const double t = 1e-4 * i;
    core::ImuSample s;
    s.stamp_s = t;
    s.outputs = Eigen::Vector3d(0.1, 0.2, 9.8);
    assembler.add_sample(s);
    ++samples;
    if (i % 100 == 50) assembler.add_channel_sample({core::Channel::Temperature, t, 25.0});
  }
  // Everything is still buffered: the newest stamp is within the window of the first.
  ASSERT_EQ(assembler.buffered_events(), samples + 1 + 24);
  ASSERT_EQ(assembler.counters().samples_used, 0u);
  const double per_sample =
      static_cast<double>(assembler.memory_bytes() - empty) / static_cast<double>(samples);
  EXPECT_LE(per_sample, 34.0);
  EXPECT_GE(per_sample, 32.0);  // the samples themselves are counted
  // Released, the buffer's bytes go back to what they were.
  assembler.flush();
  EXPECT_EQ(assembler.buffered_events(), 0u);
  EXPECT_EQ(assembler.counters().samples_used, samples);
  EXPECT_EQ(assembler.memory_bytes(), empty);
}
