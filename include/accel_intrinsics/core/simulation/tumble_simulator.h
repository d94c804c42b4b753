// A simulated hand tumble (docs/design.md section 11): a person holds the device still in random
// orientations and turns it between them, with the hand's linear acceleration during the turns.
// The outputs come from the one model (model.h: predict_outputs with a known direction), plus
// white noise, an optional slow bias (docs/design.md section 12) and optional quantization, in
// whatever unit S and O are in (m/s^2, or counts).
// Seeded and reproducible. The truth of each rest is returned beside the samples.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

struct TumbleSimulationOptions {
  Device truth;  // S, O (and effect terms of the outputs: non-linearity, drift)
  double rate_hz = 100.0;
  double noise_density = 300e-6 * kStandardGravity;  // output units / sqrt(Hz), white
  Eigen::Vector3d noise_scale = Eigen::Vector3d::Ones();
  double quantization = 0.0;  // output step (1 for integer counts); 0 = none
  int poses = 24;             // rests after the initial one
  // Up directions (unit, DUT frame) of the rests after the first; empty: uniformly random.
  std::vector<Eigen::Vector3d> up_directions;
  // Random up directions at least this far from the previous one (a person turns noticeably;
  // two rests in nearly one orientation look like one rest).
  double min_turn_deg = 20.0;
  double initial_rest_s = 10.0;  // the first rest (the device lying on the bench)
  double rest_min_s = 4.0;       // each later rest lasts uniformly in [rest_min_s, rest_max_s]
  double rest_max_s = 7.0;
  double turn_min_s = 1.5;  // each turn lasts uniformly in [turn_min_s, turn_max_s]
  double turn_max_s = 3.0;
  // Peak linear acceleration of the hand during a turn, m/s^2 (a random direction per turn).
  double turn_linear_acceleration = 2.0;
  double local_gravity = kStandardGravity;
  double start_time_s = 0.0;
  std::uint64_t seed = 1;
  // Slow bias (docs/design.md section 12), in output units, the gimbal simulator's process
  // (simulator.h SlowBiasProcess): a Gauss-Markov bias of standard deviation bias_gm_sigma and
  // correlation time bias_gm_tau_s and a random walk of bias_random_walk per sqrt(s) from 0 at
  // start_time_s, per accelerometer, added to every sample. Its own random stream: the other
  // draws of a seed are the same with or without it. 0 (default): none.
  double bias_gm_sigma = 0.0;
  double bias_gm_tau_s = 0.0;
  double bias_random_walk = 0.0;
};

struct TrueRest {
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // unit specific force, DUT frame
};

struct TumbleRecording {
  std::vector<ImuSample> samples;
  std::vector<TrueRest> rests;  // the initial rest first
};

// Throws std::invalid_argument naming the field.
void validate(const TumbleSimulationOptions& options);

TumbleRecording simulate_hand_tumble(const TumbleSimulationOptions& options);

// The noise model the options imply (white per-sample std and the slow bias; random walk from
// start_time_s): what an estimate from the first rest should find.
NoiseModel true_noise_model(const TumbleSimulationOptions& options);

// A random device near the identity: responsivities 1 +- spread, axes a few tenths of a degree
// from orthogonal, offsets up to offset_max, and with random_mounting its axes turned at random in
// the DUT frame (the intrinsics do not depend on it, S does). For the tests' and the demo's
// tumbles; units as S: multiply S and O by a counts scale for raw counts.
Device random_tumble_device(std::uint64_t seed, double responsivity_spread = 0.02,
                            double misalignment_rad = 0.005, double offset_max = 0.2,
                            bool random_mounting = true);

}  // namespace core
}  // namespace accel_intrinsics
