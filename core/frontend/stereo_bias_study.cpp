// measureStereoBias and its report (stereo_bias.h): the front-end on a KITTI folder, the motion-
// stereo measurement on its frames and on the two halves of them, as text and as a config fragment.

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/common/error.h"
#include "core/common/statistics.h"
#include "core/frontend/stereo_bias.h"
#include "core/frontend/track_source.h"

namespace marglab {

namespace {

// Fewer usable observations than this: no offset is reported (a median of a handful is noise).
constexpr int kMinSamples = 10;

void checkMeasurable(const ImageSequence& images, const StereoBiasRequest& request) {
  const int first = request.first, last = request.last;
  const Sequence& seq = images.sequence;
  if (seq.kind != DatasetKind::kKitti || !images.images) {
    throw InputError(seq.directory, 0,
                     "expected a KITTI-layout folder with rectified stereo images (calib.txt with "
                     "P0 and P1, times.txt, image_0/ and image_1/)");
  }
  if (!request.poses && (!seq.hasTrajectory() || seq.gt_is_estimate)) {
    throw InputError(seq.directory, 0,
                     "no ground-truth poses (expected poses.txt beside calib.txt, or the "
                     "download's dataset/poses/NN.txt; or give --poses): motion stereo needs the "
                     "camera's poses");
  }
  const int n = static_cast<int>(images.images->t_ns.size());
  if (first < 0 || first > last || last >= n) {
    throw InputError(seq.directory, 0,
                     fmt::format("--frames {}:{}: expected FIRST:LAST with 0 <= FIRST <= LAST <= "
                                 "{} (the folder has {} stereo frames)",
                                 first, last, n - 1, n));
  }
  const int needed = 2 * request.settings.min_frames;
  if (last - first + 1 < needed) {
    throw InputError(
        seq.directory, 0,
        fmt::format("--frames {}:{}: {} frames, expected at least {} (two halves of "
                    "tracks over {} frames each, for the held-out check)",
                    first, last, last - first + 1, needed, request.settings.min_frames));
  }
}

// A pose this close in time to a frame is the frame's (KITTI frames are 100 ms apart; a TUM file
// of a run holds the frame times to the nanosecond).
constexpr int64_t kPoseTimeToleranceNs = 1'000'000;

// T_w_c0 at every frame 0..last of the stream from `trajectory` (poses T_w_b, T_b_c0 given).
std::vector<SE3<double>> framePoses(const Trajectory& trajectory, const SE3<double>& T_b_c0,
                                    const std::string& source, const TrackStream& stream,
                                    int last) {
  std::vector<SE3<double>> poses;
  const std::vector<int64_t>& times = trajectory.t_ns;
  for (int k = 0; k <= last; ++k) {
    const int64_t t = stream.frames[static_cast<std::size_t>(k)].t_ns;
    auto it = std::lower_bound(times.begin(), times.end(), t - kPoseTimeToleranceNs);
    if (it == times.end() || *it > t + kPoseTimeToleranceNs) {
      throw InputError(source, 0,
                       fmt::format("frame {} (t = {:.6f} s) has no pose: expected one pose per "
                                   "frame of times.txt, within 1 ms of its time",
                                   k, 1e-9 * static_cast<double>(t)));
    }
    if (it + 1 != times.end() && std::abs(*(it + 1) - t) < std::abs(*it - t)) ++it;
    const std::size_t i = static_cast<std::size_t>(it - times.begin());
    poses.push_back(SE3<double>(trajectory.q_w_b[i], trajectory.p_w_b[i]) * T_b_c0);
  }
  return poses;
}

double offsetOf(const std::vector<DisparitySample>& samples, OffsetStatistic statistic,
                double min_noise_px) {
  if (statistic == OffsetStatistic::kFitIntercept) return fitOffsetScale(samples, min_noise_px).c;
  std::vector<double> e;
  for (const DisparitySample& s : samples) e.push_back(s.error());
  return median(std::move(e));
}

// Each half of [first, last] measured alone, its offset applied to the other half.
std::vector<HeldOutCheck> heldOut(const TrackStream& stream, const std::vector<SE3<double>>& poses,
                                  const StereoBiasStudy& study) {
  const MotionStereoSettings& settings = study.settings;
  const int first = study.first, last = study.last;
  const int mid = first + (last - first) / 2;
  const int range[2][2] = {{first, mid}, {mid + 1, last}};
  std::vector<DisparitySample> half[2];
  for (int h = 0; h < 2; ++h) {
    half[h] = motionStereoSamples(stream, poses, study.stereo, range[h][0], range[h][1], settings);
    if (static_cast<int>(half[h].size()) < kMinSamples) return {};
  }
  std::vector<HeldOutCheck> checks;
  for (int h = 0; h < 2; ++h) {
    HeldOutCheck c;
    c.measure_first = range[h][0];
    c.measure_last = range[h][1];
    c.test_first = range[1 - h][0];
    c.test_last = range[1 - h][1];
    c.n_measure = static_cast<int>(half[h].size());
    c.n_test = static_cast<int>(half[1 - h].size());
    c.offset = offsetOf(half[h], study.statistic, settings.min_noise_px);
    c.test_before = offsetOf(half[1 - h], study.statistic, settings.min_noise_px);
    c.test_after = c.test_before - c.offset;
    checks.push_back(c);
  }
  return checks;
}

}  // namespace

StereoBiasStudy measureStereoBias(const ImageSequence& images, const StereoBiasRequest& request) {
  checkMeasurable(images, request);
  const Sequence& seq = images.sequence;
  StereoBiasStudy study;
  study.dataset = request.dataset;
  study.sequence = seq.name;
  study.first = request.first;
  study.last = request.last;
  study.settings = request.settings;
  study.config_shift_px = request.config_shift_px;
  study.width = seq.calib.cam0.width;
  study.height = seq.calib.cam0.height;
  study.stereo = {seq.calib.cam0.fx, seq.calib.cam0.cx, seq.calib.cam1.cx, seq.calib.cam0.cy,
                  seq.calib.baseline()};
  const ImageTracking tracking =
      trackImages(images, resolveFrontendOptions(request.frontend, seq.kind),
                  static_cast<std::size_t>(request.last) + 1);
  std::vector<SE3<double>> poses;
  if (request.poses) {
    study.poses = request.poses_file + " (not ground truth: offset = the fit's intercept c)";
    study.statistic = OffsetStatistic::kFitIntercept;
    poses = framePoses(*request.poses, SE3<double>(), request.poses_file, tracking.stream,
                       request.last);
  } else {
    study.poses = "ground truth (" + seq.gt_source + ")";
    const SE3<double> T_b_c0(seq.calib.cam0.R_b_c, seq.calib.cam0.t_b_c);
    poses = framePoses(seq.gt, T_b_c0, seq.gt_source, tracking.stream, request.last);
  }
  const std::vector<DisparitySample> samples =
      motionStereoSamples(tracking.stream, poses, study.stereo, study.first, study.last,
                          study.settings, &study.tracks_used);
  if (static_cast<int>(samples.size()) < kMinSamples) {
    throw InputError(seq.directory, 0,
                     fmt::format("frames {}:{}: {} usable stereo observations, expected at least "
                                 "{} (too little motion, or too few long tracks)",
                                 study.first, study.last, samples.size(), kMinSamples));
  }
  study.summary =
      summarizeDisparityErrors(samples, study.settings.min_noise_px, study.width, study.height);
  study.vertical =
      verticalMisalignment(tracking.stream, study.first, study.last, study.width, study.height);
  study.held_out = heldOut(tracking.stream, poses, study);
  return study;
}

namespace {

void binTable(std::ostringstream& out, const char* title, const char* unit,
              const std::vector<ErrorBin>& bins) {
  out << fmt::format("\nby {}:\n{:>14} {:>6} {:>9} {:>9} {:>7} {:>10} {:>9}\n", title, unit, "n",
                     "median e", "mean e", "s.e.", "depth err", "v1 - v0");
  for (const ErrorBin& b : bins) {
    const std::string range =
        std::isinf(b.hi) ? fmt::format("{:g}+", b.lo) : fmt::format("{:g}-{:g}", b.lo, b.hi);
    out << fmt::format("{:>14} {:>6} {:>+9.3f} {:>+9.3f} {:>7.3f} {:>+9.2f}% {:>+9.3f}\n", range,
                       b.n, b.median, b.mean, b.se, 100 * b.rel_depth_error, b.dv);
  }
}

void verticalTable(std::ostringstream& out, const VerticalField& v) {
  out << fmt::format(
      "\nvertical misalignment v1 - v0 [px] of every stereo match ({} matches, median {:+.3f}), "
      "median per cell (rows v0, columns u0):\n{:>10}",
      v.n, v.overall, "");
  for (std::size_t c = 0; c + 1 < v.column_edges.size(); ++c) {
    out << fmt::format(" {:>9}", fmt::format("{}-{}", v.column_edges[c], v.column_edges[c + 1]));
  }
  out << "\n";
  const std::size_t cols = v.column_edges.size() - 1;
  for (std::size_t r = 0; r + 1 < v.row_edges.size(); ++r) {
    out << fmt::format("{:>10}", fmt::format("{}-{}", v.row_edges[r], v.row_edges[r + 1]));
    for (std::size_t c = 0; c < cols; ++c) {
      const double m = v.median_dv[r * cols + c];
      out << (std::isnan(m) ? fmt::format(" {:>9}", "-") : fmt::format(" {:>+9.3f}", m));
    }
    out << "\n";
  }
}

void heldOutTable(std::ostringstream& out, const std::vector<HeldOutCheck>& checks,
                  OffsetStatistic statistic) {
  const char* name = statistic == OffsetStatistic::kMedian ? "median e" : "fit c";
  out << fmt::format(
      "\nheld out (each half measured alone, its offset ({}) applied to the other half):\n", name);
  if (checks.empty()) {
    out << "  not available: a half has fewer than 10 usable observations\n";
    return;
  }
  for (const HeldOutCheck& c : checks) {
    out << fmt::format(
        "  measured on frames {}:{} ({} obs): offset {:+.3f} px; on frames {}:{} ({} obs) {} "
        "{:+.3f} px as given, {:+.3f} px after the correction\n",
        c.measure_first, c.measure_last, c.n_measure, c.offset, c.test_first, c.test_last, c.n_test,
        name, c.test_before, c.test_after);
  }
}

}  // namespace

std::string stereoBiasReport(const StereoBiasStudy& study) {
  const RectifiedStereo& st = study.stereo;
  const DisparityErrorSummary& s = study.summary;
  const MotionStereoSettings& set = study.settings;
  std::ostringstream out;
  out << fmt::format("stereo disparity against motion stereo: {} ({}), frames {}:{}\n",
                     study.dataset, study.sequence, study.first, study.last);
  out << fmt::format(
      "calibration: f = {:.4f} px, cx0 = {:.4f}, cx1 = {:.4f} (right_cx_shift_px {:+.4f} "
      "applied), cy = {:.4f}, b = {:.6f} m\n",
      st.f, st.cx0, st.cx1, study.config_shift_px, st.cy, st.baseline_m);
  out << fmt::format(
      "settings: tracks over >= {} frames and >= {:.2f} m, left RMS <= {:.2f} px, sigma(f b / z) "
      "<= {:.2f} px, noise floor {:.2f} px\n",
      set.min_frames, set.min_motion_m, set.max_rms_px, set.max_sigma_px, set.min_noise_px);
  out << "poses: " << study.poses << "\n";
  out << fmt::format("{} tracks triangulated from motion, {} stereo observations\n",
                     study.tracks_used, s.n);
  out << "e = (u0 - u1) - (cx0 - cx1) - f b / z_motion [px]\n";
  out << fmt::format("  median e                {:+.4f} px\n", s.median);
  out << fmt::format("  spread (1.4826 MAD)     {:.4f} px\n", s.spread);
  out << fmt::format("  mean e                  {:+.4f} px (s.e. {:.4f})\n", s.mean, s.se);
  out << fmt::format(
      "  fit e = c + s d_motion  c = {:+.4f} +- {:.4f} px, s = {:+.3f} +- {:.3f} %\n", s.fit_c,
      s.fit_c_se, 100 * s.fit_s, 100 * s.fit_s_se);
  out << fmt::format("  depth error (median -e/d)  {:+.2f} %\n", 100 * s.rel_depth_error);
  out << fmt::format("  v1 - v0 (median)        {:+.4f} px\n", s.dv);
  binTable(out, "depth z_motion", "z [m]", s.by_depth);
  binTable(out, "image column", "u0 [px]", s.by_column);
  binTable(out, "image row", "v0 [px]", s.by_row);
  verticalTable(out, study.vertical);
  heldOutTable(out, study.held_out, study.statistic);
  out << fmt::format(
      "\noffset ({}) {:+.4f} px\ncorrection: [calibration] right_cx_shift_px = {:.4f} ({:+.4f} - "
      "({:+.4f}))\n",
      study.statistic == OffsetStatistic::kMedian ? "median e" : "fit c", study.offset(),
      study.correctedShift(), study.config_shift_px, study.offset());
  return out.str();
}

std::string stereoBiasToml(const StereoBiasStudy& study, const std::string& command_line) {
  std::ostringstream out;
  out << "# " << command_line << "\n#\n";
  std::istringstream report(stereoBiasReport(study));
  for (std::string line; std::getline(report, line);)
    out << (line.empty() ? "#" : "# " + line) << "\n";
  out << "\n[calibration]\n";
  out << fmt::format("right_cx_shift_px = {:.4f}\n", study.correctedShift());
  return out.str();
}

}  // namespace marglab
