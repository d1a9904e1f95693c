#pragma once
// One run, typed: what `marglab run` is given, from its options, from a spec file or from a sweep's
// plan — the one description that the run verb, the sweep planner, its local children and its
// Slurm tasks share, validated once (runProblems, core/pipeline/run.h) before any work.
//
// A spec file is a config file (RunConfig's TOML, every key) with one more table, [run]:
//
//   [run]
//   dataset = "kitti/10"            # a shipped name or a folder
//   variant = "ns-qr-sqrt-f32"
//   seed = 1                        # an integer, or a string above 2^63 - 1
//   frames = 0                      # 0: the whole sequence
//   mode = "auto"                   # auto | vo | vio
//   imu = "synthetic"               # synthetic | real
//   frontend = "auto"               # auto | images | simulated
//   tracks = ""                     # a track file instead of a front-end ("": none)
//   tracks_any_sequence = false
//   isa = "auto"                    # auto | sse2 | avx2 | avx512
//   set = ["lm.max_iterations=3"]   # the --set overrides, as given (already in the config below)
//   output = "runs/x.h5"            # results file; its TUM trajectory beside it
//   dump_windows = []               # frames whose windows are captured
//   dump_dir = "windows"
//   [window]
//   max_kfs = 7
//   ...                             # every config key, the effective config before the dataset's
//                                   # defaults are filled in (sentinels such as -1 stay)
//
// `marglab run --spec FILE` runs it (a -o given beside it replaces `output`); a sweep writes one
// per run (runs/<id>.spec.toml) and its children run them; every results file records its run's
// spec (root attribute run_spec), so a run can be repeated from its results file too.

#include <cstdint>
#include <string>
#include <vector>

#include "core/common/enum_names.h"
#include "core/estimator/variant.h"
#include "core/frontend/track_source.h"
#include "core/pipeline/run_config.h"

namespace marglab {

// VO: stereo only (the state is the left camera). VIO: stereo + IMU (the state is the body).
// kAuto: VIO where the dataset has an IMU and ground truth (EuRoC, TUM-VI), VO on KITTI.
enum class RunMode { kAuto, kVo, kVio };
inline constexpr EnumNames<RunMode, 3> kRunModeNames{
    {{RunMode::kAuto, "auto"}, {RunMode::kVo, "vo"}, {RunMode::kVio, "vio"}}};

// The IMU of a VIO run: synthesized from the spline (default), or the sequence's recording.
enum class ImuSource { kSynthetic, kReal };
inline constexpr EnumNames<ImuSource, 2> kImuSourceNames{
    {{ImuSource::kSynthetic, "synthetic"}, {ImuSource::kReal, "real"}}};

struct RunSpec {
  std::string dataset;  // "kitti/10", "euroc/MH_01_easy", or a folder in original layout
  Variant variant;
  RunMode mode = RunMode::kAuto;
  ImuSource imu = ImuSource::kSynthetic;
  // Where the tracks come from (core/frontend/track_source.h): a track file when tracks_file is
  // set, else the images or the simulation (auto: images where the folder has them).
  FrontendKind frontend = FrontendKind::kAuto;
  std::string tracks_file;
  bool tracks_any_sequence = false;  // a track file of another sequence is accepted
  int max_frames = 0;                // 0: the whole sequence
  std::uint64_t seed = 1;
  std::string isa = "auto";  // the kernels' instruction set (core/linalg/isa.h)
  // defaults < config file < --set < options; each key's origin recorded for messages.
  RunConfig config;
  std::vector<std::string> overrides;  // the --set assignments as given, in order
  std::string output;  // results file (.h5); the TUM trajectory goes to <output minus .h5>.tum
  // Window capture: the windows of these frame indices (0-based, before their optimization, with
  // the step taken) are written to dump_dir (core/estimator/window_io.h).
  std::vector<int> dump_windows;
  std::string dump_dir = "windows";
  // Fault injection for tests of the failure path: a NaN in the first measurement of this frame.
  int inject_nan_frame = -1;

  // The spec file's text (above); fromToml(toToml()) gives the same spec.
  std::string toToml() const;
  // Reads a spec file; throws InputError naming the file and line (unknown keys, wrong types,
  // values outside their range, an unknown variant).
  static RunSpec fromTomlFile(const std::string& path);
  static RunSpec fromTomlString(const std::string& text, const std::string& name);
};

}  // namespace marglab
