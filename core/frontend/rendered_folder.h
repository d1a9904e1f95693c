#pragma once
// `marglab datasets render`: a dataset folder of stereo images rendered from the simulated world
// (world_render.h) along a shipped sequence's trajectory, through its real camera model, at its
// real frame times, in the dataset's ORIGINAL layout — so that `marglab run --dataset FOLDER` and
// `marglab datasets check FOLDER` read it as they read a download (core/data/sequence.h,
// image_folder.h), without borrowing anything from the shipped sequence: motion with known pixel
// truth through every camera model.
//
// Plan (planRendering). The C² spline through the sequence's ground truth (trajectory_spline.h),
// the world around it (renderWorldOptions, makeWorld with the seed), and the frames: the
// sequence's real camera timestamps inside the ground truth, from start_s seconds after its first
// pose on, the first N. Image size: the real calibration's (EuRoC 752×480, TUM-VI 512×512).
// KITTI's calib.txt has none; the recorded size per sequence is used (kittiImageSize: 00–02
// 1241×376, 03 1242×375, 04–10 1226×370).
//
// What is written (writeRenderedFolder). The truth is the spline: the images are rendered at its
// poses, and the ground truth written is the spline at the sequence's ground-truth times from 1 s
// before the first frame to 1 s after the last (clipped to the trajectory).
//   EuRoC / TUM-VI (ASL)  mav0/cam{0,1}/data.csv ("#timestamp [ns],filename") + data/<t_ns>.png;
//       calibration: copies of the files the sequence was loaded from — EuRoC
//       mav0/cam{0,1}/sensor.yaml, TUM-VI dso/camchain.yaml (where TUM-VI's export keeps it, and
//       what the loader reads), with its cameras also as mav0/cam{0,1}/sensor.yaml;
//       mav0/imu0/data.csv: the IMU synthesized along the same spline (imu_synth.h) at the real
//       recording's median rate (200 Hz without one), with the sequence's noise densities and
//       bias random walk (seed-derived), starting at zero bias; mav0/imu0/sensor.yaml: those
//       densities; ground truth: EuRoC mav0/state_groundtruth_estimate0/data.csv (17 columns,
//       with the spline's velocity and the synthesized IMU's true biases), TUM-VI
//       mav0/mocap0/data.csv (8 columns).
//   KITTI  sequences/NN/image_{0,1}/NNNNNN.png, sequences/NN/times.txt (the frames' times in s,
//       exact to the ns), sequences/NN/calib.txt (copy), poses/NN.txt (the spline's T_w_cam0 at
//       the frames). No IMU (KITTI odometry has none).
//   README.txt  marglab version, command, sequence, seed, what the pixels are.
// Numbers are written in their shortest exact decimal form, so loading the folder gives the same
// calibration, timestamps and ground truth bit for bit (quaternions up to their normalization).
// Atomic like every output (core/common/atomic_file.h): everything is written into the sibling
// "<FOLDER>.tmp-<pid>" and renamed onto FOLDER at the end; on an error or an interrupt the
// temporary is removed. An existing non-empty FOLDER (or a file) is refused before anything is
// rendered.

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/data/types.h"
#include "core/frontend/world_render.h"
#include "core/sim/trajectory_spline.h"
#include "core/sim/world.h"

namespace marglab {

struct RenderPlan {
  Sequence sequence;  // as loaded, KITTI cameras at the recorded image size
  std::unique_ptr<TrajectorySpline> spline;
  World world;
  RenderOptions render;
  std::vector<int64_t> t_ns;  // the frames
  uint64_t seed = 0;
  double start_s = 0;
};

// The recorded image size of KITTI odometry sequence NN (00–10), {0, 0} for another name.
std::pair<int, int> kittiImageSize(const std::string& sequence_number);

// Throws InputError: a name that is not a shipped sequence with a trajectory (naming the
// available ones), frames < 1 or more than the sequence has from start_s on, start_s < 0 or
// beyond the ground truth.
RenderPlan planRendering(const std::string& dataset, long long frames, double start_s,
                         uint64_t seed);

struct RenderSummary {
  std::size_t frames = 0;
  int width = 0, height = 0;
  std::string camera_model;  // "radtan", "equidistant", "pinhole (rectified)"
};

// Throws InputError naming the folder or file (existing non-empty folder, write failure) and
// Interrupted (core/common/interrupt.h) on SIGINT / SIGTERM; FOLDER is then untouched.
RenderSummary writeRenderedFolder(const RenderPlan& plan, const std::string& folder,
                                  const std::string& command_line);

}  // namespace marglab
