#pragma once
// Finding and loading a whole sequence, and validating it (`marglab datasets check`).
//
// Names. "euroc/MH_01_easy", "tumvi/room1" (alias "tumvi/dataset-room1_512_16"), "kitti/00" name a
// sequence shipped in the datasets folder, which is
//   $MARGLAB_DATASETS if set, else sourceDir() + "/datasets" (core/common/source_dir.h).
// Anything else that is an existing directory is loaded as a user folder, in one of the layouts:
//   shipped layout   <dir>/cam0_timestamps_ns.txt[.gz], gt_asl.csv / gt_tum.txt /
//   estimate_*_tum.txt,
//                    imu0_asl.csv; calibration from <dir>/../calib/, the dataset kind from the
//                    parent folder's name (euroc or tumvi).
//   ASL (EuRoC, TUM-VI)  <dir>/mav0/ (or <dir> = mav0): state_groundtruth_estimate0/data.csv
//   (EuRoC)
//                    or mocap0/data.csv (TUM-VI), imu0/data.csv, cam0/data.csv; EuRoC calibration
//                    from cam0/sensor.yaml + cam1/sensor.yaml, IMU noise from imu0/sensor.yaml when
//                    it has the densities; TUM-VI calibration from a Kalibr camchain found in
//                    <dir>, <dir>/dso or mav0 (camchain.yaml, *imucam*.yaml), else the shipped
//                    TUM-VI one; its IMU noise from imu0/sensor.yaml when present, else the
//                    shipped TUM-VI one.
//   KITTI            <dir>/times.txt + calib.txt, poses from <dir>/poses.txt or the official
//                    <dir>/../../poses/<NN>.txt; or the download's root <dir> with
//                    <dir>/sequences/NN when it holds exactly one sequence.
// Every file may also be gzip-compressed (name + ".gz").
//
// Preference when several GT files exist: the ASL csv (exact ns timestamps, and GT velocity and
// biases for EuRoC) over the TUM txt (times rounded to 10 µs). A folder without any trajectory
// loads as "timestamps only" (Sequence::hasTrajectory() is false).

#include <string>
#include <vector>

#include "core/data/types.h"

namespace marglab {

std::string datasetsRoot();

// Names of the shipped sequences, sorted by dataset (euroc, tumvi, kitti) then name.
std::vector<std::string> listSequences();

struct LoadOptions {
  bool load_imu = true;  // false: only record whether a real IMU file exists (imu_file)
};

// A sequence argument as it enters (--dataset, a sweep's datasets): a shipped name unchanged but
// for the TUM-VI export's folder names; a folder path lexically normalized without trailing
// slashes, so that "x", "x/" and "./x/" (tab completion) name one dataset, called "x".
std::string normalizeDatasetArgument(const std::string& name_or_path);

// Throws InputError: for an unknown name (listing the available ones), an unreadable folder, any
// bad file or an implausible sequence (core/data/plausibility.h).
Sequence loadSequence(const std::string& name_or_path, const LoadOptions& options = {});

// The dataset kind of a sequence from its folder's layout, without loading it (for validating
// plans); throws InputError as loadSequence does for an unknown name or unreadable folder.
DatasetKind sequenceKind(const std::string& name_or_path);

// Indices [first, last) of the camera frames inside the trajectory's time span (empty if none).
std::pair<std::size_t, std::size_t> framesWithinTrajectory(const Sequence& sequence);

// Result of validating a loaded sequence beyond the per-line checks of the parsers.
struct SequenceCheck {
  bool timestamps_only = false;  // no trajectory: only camera timestamps (and calibration)
  double duration_s = 0;         // camera timestamps span
  std::size_t frames = 0;
  std::size_t frames_in_gt = 0;  // camera frames within the trajectory span
  double max_gt_gap_s = 0;
  double imu_rate_hz = 0;  // median rate; 0 without IMU
  std::vector<std::string> notes;
};

// Checks: camera timestamps within the trajectory span (at least one frame), trajectory sample
// gaps, real IMU rate within 10 % of 200 Hz and covering the frames inside the GT span. Throws
// InputError naming the file and what was expected when a check fails.
SequenceCheck checkSequence(const Sequence& sequence);

// The IMU part of checkSequence, which `run --imu real` runs before any work: a real IMU at
// 200 Hz ± 10 % that covers the camera frames (within the trajectory). Returns the median rate
// (0 without an IMU); throws InputError naming the IMU file and what was expected.
double checkImuCoverage(const Sequence& sequence);

}  // namespace marglab
