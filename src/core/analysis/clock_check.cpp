#include "accel_intrinsics/core/analysis/clock_check.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "accel_intrinsics/core/fit/fit.h"

namespace accel_intrinsics {
namespace core {

std::string ClockCheckResult::message(const std::string& fix_option) const {
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << "IMU stamps are " << std::abs(offset_s) << " s "
    << (offset_s > 0.0 ? "later" : "earlier") << " than the gimbal's (" << std::setprecision(0)
    << 100.0 * explained_at_offset << " % of the IMU motion falls inside the gimbal's moves when "
    << "shifted, " << 100.0 * explained_at_zero << " % unshifted): clocks not synchronized; pass "
    << fix_option << " " << std::setprecision(2) << -offset_s;
  return s.str();
}

ClockCheck::ClockCheck(const ClockCheckOptions& options) : options_(options) {
  reset();
}

void ClockCheck::reset() {
  commands_.clear();
  chunks_.clear();
  last_chunk_ = chunks_.end();
  bins_used_ = 0;
  first_bin_ = last_bin_ = 0;
  samples_ = 0;
  have_origin_ = false;
  bins_refused_ = 0;
  total_sum_.setZero();
  stills_.clear();
  newest_chunk_ = next_evaluated_chunk_ = 0;
  still_motion_.clear();
  all_motion_.clear();
}

void ClockCheck::add_command(const GimbalEvent& event) {
  if (std::isfinite(event.stamp_s)) commands_.push_back(event);
}

void ClockCheck::add_sample(const ImuSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.outputs.allFinite()) return;
  if (!have_origin_) {
    have_origin_ = true;
    origin_s_ = sample.stamp_s;
    newest_chunk_ = next_evaluated_chunk_ = 0;
  }
  const double k_real = std::floor((sample.stamp_s - origin_s_) / options_.bin_s);
  if (std::abs(k_real) * options_.bin_s > options_.max_span_s) {
    ++bins_refused_;
    return;
  }
  const auto k = static_cast<std::int64_t>(k_real);
  // Floor division: chunk c holds bins [c kChunkBins, (c + 1) kChunkBins).
  const std::int64_t c = (k >= 0 ? k : k - (kChunkBins - 1)) / kChunkBins;
  // Samples come nearly in order: most land in the chunk of the previous one.
  if (last_chunk_ == chunks_.end() || last_chunk_->first != c) {
    auto found = chunks_.find(c);
    if (found == chunks_.end()) {
      if (add_to_still(k, sample.outputs)) {  // a late sample of a rest already summarized
        total_sum_ += sample.outputs;
        ++samples_;
        return;
      }
      found = chunks_.try_emplace(c).first;
      found->second.resize(kChunkBins);
    }
    last_chunk_ = found;
    if (c > newest_chunk_) {
      newest_chunk_ = c;
      collapse_before(c);
    }
  }
  Bin& bin = last_chunk_->second[static_cast<std::size_t>(k - c * kChunkBins)];
  if (bin.n == 0) {
    if (bins_used_ == 0 || k < first_bin_) first_bin_ = k;
    if (bins_used_ == 0 || k > last_bin_) last_bin_ = k;
    ++bins_used_;
  }
  bin.sum += sample.outputs;
  ++bin.n;
  total_sum_ += sample.outputs;
  ++samples_;
}

std::size_t ClockCheck::memory_bytes() const {
  // A map node: the chunk's vector and key, and the tree's links (about 4 pointers).
  constexpr std::size_t kNode = sizeof(std::pair<const std::int64_t, Chunk>) + 4 * sizeof(void*);
  constexpr std::size_t kStillNode =
      sizeof(std::pair<const std::int64_t, Still>) + 4 * sizeof(void*);
  std::size_t stills = 0;
  for (const auto& [first, still] : stills_) {
    stills += kStillNode + (still.head.capacity() + still.tail.capacity()) * sizeof(Bin) +
              still.loud.capacity() * sizeof(still.loud[0]);
  }
  return sizeof(*this) + commands_.capacity() * sizeof(GimbalEvent) +
         chunks_.size() * (kNode + kChunkBins * sizeof(Bin)) + stills +
         still_motion_.memory_bytes() + all_motion_.memory_bytes() - 2 * sizeof(LogHistogram);
}

namespace {

struct Move {
  double start_s;
  double end_s;
};

// The IMU stream as bins from `origin_s`: cumulative sums and counts, and the motion signal.
struct Binned {
  double origin_s = 0.0;
  double bin_s = 0.0;
  std::size_t size = 0;
  std::vector<Eigen::Vector3d> cum_sum;  // size + 1
  std::vector<double> cum_n;             // size + 1
  std::vector<double> motion;            // above the noise floor, at bin boundaries 0..size
  std::vector<double> cum_motion;        // size + 2
  double total_motion = 0.0;

  // Index of the first bin boundary at or after t, clamped to [0, size].
  std::size_t boundary_at(double t_s) const {
    const double k = std::ceil((t_s - origin_s) / bin_s);
    if (k <= 0.0) return 0;
    return k >= static_cast<double>(size) ? size : static_cast<std::size_t>(k);
  }
  double motion_between(double t0_s, double t1_s) const {
    if (!(t1_s > t0_s)) return 0.0;
    const double k0 = std::ceil((t0_s - origin_s) / bin_s);
    const double k1 = std::ceil((t1_s - origin_s) / bin_s);
    auto at = [&](double k) {
      if (k <= 0.0) return 0.0;
      if (k >= static_cast<double>(size + 1)) return total_motion;
      return cum_motion[static_cast<std::size_t>(k)];
    };
    return at(k1) - at(k0);
  }
};

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct MoveEdges {
  std::size_t moves = 0;
  double start_gap_s = 0.0;         // median over moves: motion start (edge share reached) - MOVING
  double end_gap_s = 0.0;           // median over moves: SETTLED - motion end (1 - edge share left)
  double start_gap_spread_s = 0.0;  // median absolute deviation of the start gaps
  double duration_s = 0.0;          // median over moves: motion end - motion start
};

// The motion's edges in each step move's window (the move shifted by `shift`, padded): the first
// bin boundary where `share` of the window's motion has passed, and the first where 1 - share has.
template <typename IsStep>
MoveEdges move_edges(const Binned& b, const std::vector<Move>& moves, double shift, double pad,
                     double share, IsStep is_step) {
  std::vector<double> starts, ends, durations;
  for (const Move& m : moves) {
    if (!is_step(m)) continue;
    const std::size_t lo = b.boundary_at(m.start_s + shift - pad);
    const std::size_t hi = std::min(b.size, b.boundary_at(m.end_s + shift + pad));
    double weight = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) weight += b.motion[k];
    if (!(weight > 0.0)) continue;
    double passed = 0.0;
    double t_start = std::nan(""), t_end = std::nan("");
    for (std::size_t k = lo; k <= hi; ++k) {
      passed += b.motion[k];
      const double t = b.origin_s + static_cast<double>(k) * b.bin_s;
      if (std::isnan(t_start) && passed >= share * weight) t_start = t;
      if (std::isnan(t_end) && passed >= (1.0 - share) * weight) t_end = t;
    }
    if (std::isnan(t_start) || std::isnan(t_end)) continue;
    starts.push_back(t_start - m.start_s);
    ends.push_back(m.end_s - t_end);
    durations.push_back(t_end - t_start);
  }
  MoveEdges e;
  e.moves = starts.size();
  if (starts.empty()) return e;
  e.start_gap_s = median(starts);
  e.end_gap_s = median(ends);
  e.duration_s = median(durations);
  for (double& s : starts) s = std::abs(s - e.start_gap_s);
  e.start_gap_spread_s = median(starts);
  return e;
}

}  // namespace

ClockCheckResult ClockCheck::result() const {
  ClockCheckResult r;
  std::vector<GimbalEvent> commands = commands_;
  std::stable_sort(
      commands.begin(), commands.end(),
      [](const GimbalEvent& a, const GimbalEvent& b) { return a.stamp_s < b.stamp_s; });
  // The gimbal's moves (MOVING to the next SETTLED or DONE) and dwells (SETTLED to the next
  // command).
  std::vector<Move> moves;
  double move_start = std::nan("");
  for (const GimbalEvent& c : commands) {
    if (c.state == GimbalState::Moving) {
      if (std::isnan(move_start)) move_start = c.stamp_s;
    } else if (!std::isnan(move_start)) {
      moves.push_back({move_start, c.stamp_s});
      move_start = std::nan("");
    }
  }
  if (moves.size() < 3) {
    r.not_checked_why = "fewer than 3 gimbal moves";
    return r;
  }
  if (bins_used_ < 10) {
    r.not_checked_why = "too few IMU samples";
    return r;
  }

  const double span_s = static_cast<double>(last_bin_ - first_bin_ + 1) * options_.bin_s;
  if (static_cast<double>(samples_) / span_s < options_.min_rate_hz) {
    r.not_checked_why = "IMU rate below " + std::to_string(static_cast<int>(options_.min_rate_hz)) +
                        " Hz: too sparse to see the moves";
    return r;
  }

  Binned b;
  b.bin_s = options_.bin_s;
  const std::int64_t k0 = first_bin_;
  b.origin_s = origin_s_ + static_cast<double>(k0) * options_.bin_s;
  b.size = static_cast<std::size_t>(last_bin_ - k0 + 1);
  b.cum_sum.assign(b.size + 1, Eigen::Vector3d::Zero());
  b.cum_n.assign(b.size + 1, 0.0);
  for (const auto& [c, chunk] : chunks_) {
    for (std::int64_t i = 0; i < kChunkBins; ++i) {
      const Bin& bin = chunk[static_cast<std::size_t>(i)];
      if (bin.n == 0) continue;
      const std::int64_t k = c * kChunkBins + i;
      b.cum_sum[k - k0 + 1] = bin.sum;
      b.cum_n[k - k0 + 1] = static_cast<double>(bin.n);
    }
  }
  // The still stretches: their kept bins, and their middle spread evenly over its bins (the rest
  // is still: its mean is the same throughout). Boundaries inside them have no motion here: their
  // values are in still_motion_.
  std::vector<char> inside(b.size + 1, 0);
  for (const auto& [first, still] : stills_) {
    auto put = [&](std::int64_t k, const Eigen::Vector3d& sum, double n) {
      if (n <= 0.0 || k < k0 || k - k0 >= static_cast<std::int64_t>(b.size)) return;
      b.cum_sum[static_cast<std::size_t>(k - k0 + 1)] = sum;
      b.cum_n[static_cast<std::size_t>(k - k0 + 1)] = n;
    };
    const auto edge = static_cast<std::int64_t>(still.head.size());
    for (std::int64_t i = 0; i < edge; ++i) {
      const Bin& h = still.head[static_cast<std::size_t>(i)];
      const Bin& t = still.tail[static_cast<std::size_t>(i)];
      put(first + i, h.sum, static_cast<double>(h.n));
      put(still.last - edge + 1 + i, t.sum, static_cast<double>(t.n));
    }
    const std::int64_t middle = still.last - first + 1 - 2 * edge;
    for (std::int64_t k = first + edge; k <= still.last - edge; ++k) {
      put(k, still.middle_sum / static_cast<double>(middle),
          static_cast<double>(still.middle_n) / static_cast<double>(middle));
    }
    for (std::int64_t k = std::max(first + 1, k0);
         k <= still.last && k - k0 <= static_cast<std::int64_t>(b.size); ++k) {
      inside[static_cast<std::size_t>(k - k0)] = 1;
    }
  }
  for (std::size_t k = 0; k < b.size; ++k) {
    b.cum_sum[k + 1] += b.cum_sum[k];
    b.cum_n[k + 1] += b.cum_n[k];
  }
  // Motion at boundary k: change of the mean between blocks [k-L, k) and [k, k+L).
  const auto block =
      static_cast<std::size_t>(std::max(1.0, std::round(options_.block_s / options_.bin_s)));
  b.motion.assign(b.size + 1, 0.0);
  std::vector<double> seen;
  for (std::size_t k = block; k + block <= b.size; ++k) {
    if (inside[k] != 0) continue;
    const double n_before = b.cum_n[k] - b.cum_n[k - block];
    const double n_after = b.cum_n[k + block] - b.cum_n[k];
    if (n_before <= 0.0 || n_after <= 0.0) continue;
    const Eigen::Vector3d before = (b.cum_sum[k] - b.cum_sum[k - block]) / n_before;
    const Eigen::Vector3d after = (b.cum_sum[k + block] - b.cum_sum[k]) / n_after;
    b.motion[k] = (after - before).cwiseAbs().sum();
    seen.push_back(b.motion[k]);
  }
  for (const auto& [first, still] : stills_) {
    for (const auto& [k, m] : still.loud) {
      if (k < k0 + static_cast<std::int64_t>(block) ||
          k - k0 + static_cast<std::int64_t>(block) > static_cast<std::int64_t>(b.size))
        continue;
      b.motion[static_cast<std::size_t>(k - k0)] = m;
      seen.push_back(m);
    }
  }
  if (seen.empty() && still_motion_.count() == 0) {
    r.not_checked_why = "the IMU stream has gaps everywhere";
    return r;
  }
  // Noise floor: most of the time the DUT rests, so the median is noise (and round-off of the
  // output level when there is no noise).
  // (The still stretches' values are counted to 0.5 %: their histogram.)
  double median_motion = 0.0;
  if (still_motion_.count() == 0) {
    std::nth_element(seen.begin(), seen.begin() + seen.size() / 2, seen.end());
    median_motion = seen[seen.size() / 2];
  } else {
    std::sort(seen.begin(), seen.end());
    median_motion = still_motion_.at_rank_with(seen, (seen.size() + still_motion_.count()) / 2);
  }
  const Eigen::Vector3d level = b.cum_sum[b.size] / std::max(1.0, b.cum_n[b.size]);
  const double floor = std::max(3.0 * median_motion, 1e-9 * (1.0 + level.norm()));
  b.cum_motion.assign(b.size + 2, 0.0);
  for (std::size_t k = 0; k <= b.size; ++k) {
    b.motion[k] = std::max(0.0, b.motion[k] - floor);
    b.cum_motion[k + 1] = b.cum_motion[k] + b.motion[k];
  }
  b.total_motion = b.cum_motion[b.size + 1];
  if (!(b.total_motion > 0.0)) {
    r.not_checked_why = "the IMU outputs do not change";
    return r;
  }

  const double pad = static_cast<double>(block) * options_.bin_s;
  // Share of the IMU motion inside the moves when IMU stamps = gimbal time + shift.
  std::vector<double> durations;
  for (const Move& m : moves) durations.push_back(m.end_s - m.start_s);
  std::nth_element(durations.begin(), durations.begin() + durations.size() / 2, durations.end());
  const double typical_move = durations[durations.size() / 2];
  // Step moves (not remounts, whose motion has no particular profile).
  auto is_step = [&](const Move& m) { return m.end_s - m.start_s <= 1.5 * typical_move; };
  auto explained = [&](double shift, double pad, bool steps_only = false) {
    double in_moves = 0.0;
    double covered_until = -HUGE_VAL;  // padded moves may overlap: count each bin once
    for (const Move& m : moves) {
      if (steps_only && !is_step(m)) continue;
      const double lo = std::max(m.start_s + shift - pad, covered_until);
      const double hi = m.end_s + shift + pad;
      in_moves += b.motion_between(lo, hi);
      covered_until = std::max(covered_until, hi);
    }
    return in_moves / b.total_motion;
  };
  // Step moves' motion profile is symmetric about their midpoint.
  // Fine: shift + median(centroid of motion - midpoint of move), iterated.
  auto refine = [&](double shift) {
    for (int iteration = 0; iteration < 8; ++iteration) {
      std::vector<double> lags;
      for (const Move& m : moves) {
        if (!is_step(m)) continue;
        const std::size_t lo = b.boundary_at(m.start_s + shift - pad);
        const std::size_t hi = b.boundary_at(m.end_s + shift + pad);
        double weight = 0.0, moment = 0.0;
        for (std::size_t k = lo; k <= hi && k <= b.size; ++k) {
          weight += b.motion[k];
          moment += b.motion[k] * (b.origin_s + static_cast<double>(k) * b.bin_s);
        }
        if (weight > 0.0) lags.push_back(moment / weight - (0.5 * (m.start_s + m.end_s) + shift));
      }
      if (lags.empty()) return shift;
      std::nth_element(lags.begin(), lags.begin() + lags.size() / 2, lags.end());
      const double step = lags[lags.size() / 2];
      shift += step;
      if (std::abs(step) < 0.25 * b.bin_s) break;
    }
    return shift;
  };
  // How well the dwell means at a shift fit the rig model (RMS residual, unit weights).
  auto dwell_fit_rms = [&](double shift) {
    PositionTable table;
    for (std::size_t i = 0; i + 1 < commands.size(); ++i) {
      const GimbalEvent& c = commands[i];
      if (c.state != GimbalState::Settled) continue;
      const double t0 = c.stamp_s + shift + pad;
      const double t1 = commands[i + 1].stamp_s + shift - pad;
      const std::size_t k0 = b.boundary_at(t0), k1 = b.boundary_at(t1);
      if (k1 <= k0) continue;
      const double n = b.cum_n[k1] - b.cum_n[k0];
      if (n < 1.0) continue;
      DwellRecord row;
      row.phase = c.phase;
      row.step = c.step;
      row.angle_rad = c.angle_rad;
      row.t_start_s = c.stamp_s;
      row.t_end_s = commands[i + 1].stamp_s;
      row.n = static_cast<std::uint64_t>(n);
      row.mean = (b.cum_sum[k1] - b.cum_sum[k0]) / n;
      table.rows.push_back(row);
    }
    try {
      return fit(table).residual_rms;
    } catch (const std::exception&) {
      return HUGE_VAL;
    }
  };

  // Coarse: every shift that lets the two streams overlap, in steps of one block (the padded
  // moves are a block wider on each side, so no peak falls between steps); refine() finds the
  // shift to the bin.
  const double coarse_step = pad;
  const double lo = b.origin_s - moves.back().end_s;
  const double hi = b.origin_s + static_cast<double>(b.size) * b.bin_s - moves.front().start_s;
  const auto steps = static_cast<std::size_t>(std::ceil((hi - lo) / coarse_step)) + 1;
  std::vector<double> share(steps);
  double best = 0.0;
  for (std::size_t i = 0; i < steps; ++i) {
    share[i] = explained(lo + static_cast<double>(i) * coarse_step, pad);
    best = std::max(best, share[i]);
  }
  r.explained_at_zero = explained(0.0, pad);
  if (best < options_.min_explained) {
    r.not_checked_why = "the IMU motion does not follow the gimbal's moves at any shift";
    return r;
  }
  r.checked = true;
  // Candidates: the first shift of each plateau of near-best shares, and zero.
  std::vector<double> candidates;
  if (r.explained_at_zero >= (1.0 - options_.alias_tolerance) * best) candidates.push_back(0.0);
  for (std::size_t i = 0; i < steps; ++i) {
    const bool rising = i == 0 || share[i] > share[i - 1];
    const bool peak = i + 1 == steps || share[i] >= share[i + 1];
    if (rising && peak && share[i] >= (1.0 - options_.alias_tolerance) * best) {
      candidates.push_back(lo + static_cast<double>(i) * coarse_step);
    }
  }
  double best_shift = 0.0;
  double best_rms = HUGE_VAL;
  for (double candidate : candidates) {
    const double shift = refine(candidate);
    const double rms = dwell_fit_rms(shift);
    if (rms < best_rms) {
      best_rms = rms;
      best_shift = shift;
    }
  }
  // Step 3 (fine): where the motion starts and ends inside each step move, found with the
  // windows at the centroid's shift (which holds each move's motion whatever its profile).
  const MoveEdges e = move_edges(b, moves, best_shift, pad, options_.edge_share, is_step);
  r.start_gap_s = e.start_gap_s;
  r.end_gap_s = e.end_gap_s;
  const double mean_gap = 0.5 * (e.start_gap_s + e.end_gap_s);  // the same at every shift
  r.motion_fills_moves = e.moves == 0 || mean_gap <= options_.fill_share * typical_move;
  double shift = best_shift;
  double min_offset = options_.min_offset_s;
  bool need_gain = true;
  if (!r.motion_fills_moves) {
    // The motion takes only part of each move (a servo that overshoots and settles, a settle
    // timer, an operator): its middle says nothing, its start does. The gimbal starts turning
    // when it reports MOVING, so the IMU motion's start minus MOVING is the IMU clock's lead.
    // How fast the motion starts (the edge share is reached after it begins: 0.4 of the
    // motion's duration for a raised cosine, once the noise floor is taken off) leaves
    // max(onset_tolerance_s, onset_duration_share x that duration) of doubt. Onsets that scatter
    // between moves (an operator turning by hand) are no clock: then, as for centred moves, only a
    // shift that takes motion out of the dwells is named.
    shift = e.start_gap_s;
    min_offset = std::max(
        {min_offset, options_.onset_tolerance_s, options_.onset_duration_share * e.duration_s});
    need_gain = e.start_gap_spread_s > options_.onset_spread_s;
  }
  r.explained_at_offset = explained(shift, pad);
  r.offset_s = shift;
  r.best_shift_s = shift;
  // The shift must also put more of the motion inside the step moves themselves (unpadded): a
  // centroid off the middle of moves that already hold all the motion is no evidence of another
  // clock (a gimbal that reports SETTLED a settle time after it stopped), and leaves the dwells
  // free of motion.
  r.gain = explained(shift, 0.0, true) - explained(0.0, 0.0, true);
  r.offset_found = std::abs(shift) >= min_offset && (!need_gain || r.gain >= options_.min_gain);
  if (!r.offset_found) r.offset_s = 0.0;
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
